"""Where a result came from: the code's version and git revision, the libraries, the command
line (``fsi --version``, summary.json)."""

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


def version_line() -> str:
    """``fsi X (git R), dolfinx Y, Python Z``."""
    revision = git_revision()
    git = f" (git {revision})" if revision else ""
    return (
        f"fsi {fsi.__version__}{git}, dolfinx {dolfinx.__version__}, "
        f"Python {platform.python_version()}"
    )


def describe() -> dict:
    """summary.json's provenance: versions, git revision and the process's command line."""
    return {
        "fsi": fsi.__version__,
        "git": git_revision(),
        "dolfinx": dolfinx.__version__,
        "python": platform.python_version(),
        "command": shlex.join(sys.argv),
    }
