"""Where a result came from: the code's version and git revision, the libraries (the BLAS under
MUMPS included), the command line (``fsi --version``, summary.json)."""

from __future__ import annotations

import platform
import shlex
import subprocess
import sys
from pathlib import Path

import dolfinx

import fsi

ROOT = Path(fsi.__file__).resolve().parent.parent


def git_revision() -> str | None:
    """The checkout's commit, with ``+dirty`` if tracked files changed since; None when the
    code is not a git checkout (an installed copy) or git is missing."""
    try:
        head = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
        )
        if head.returncode != 0:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head.stdout.strip() + ("+dirty" if dirty else "")


def blas_library() -> str | None:
    """The BLAS library loaded into this process (the file the dynamic linker found for
    ``libblas.so.3``, read from /proc/self/maps): Debian's reference BLAS
    (``.../blas/libblas.so.3.*``) or an optimised one chosen by update-alternatives
    (``.../openblas-serial/libblas.so.3``). MUMPS's factorisations run on it (docs/performance.md
    compares them). None where it cannot be told."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return None
    for line in maps.splitlines():
        fields = line.split(maxsplit=5)
        if len(fields) == 6 and Path(fields[5]).name.startswith("libblas.so"):
            return fields[5]
    return None


def blas_name(path: str | None) -> str:
    """A short name of the BLAS at ``path``: ``reference`` for Debian's reference BLAS, else
    the alternative's folder (``openblas-serial``, ``openblas-pthread``, ``blis-openmp``, ...)."""
    if path is None:
        return "unknown"
    folder = Path(path).parent.name
    return "reference" if folder == "blas" else folder


def version_line() -> str:
    """``fsi X (git R), dolfinx Y, Python Z, BLAS B``."""
    revision = git_revision()
    git = f" (git {revision})" if revision else ""
    return (
        f"fsi {fsi.__version__}{git}, dolfinx {dolfinx.__version__}, "
        f"Python {platform.python_version()}, BLAS {blas_name(blas_library())}"
    )


def describe() -> dict:
    """summary.json's provenance: versions, git revision and the process's command line."""
    return {
        "fsi": fsi.__version__,
        "git": git_revision(),
        "dolfinx": dolfinx.__version__,
        "python": platform.python_version(),
        "blas": blas_library(),
        "command": shlex.join(sys.argv),
    }
