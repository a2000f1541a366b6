"""Nothing is written outside ``--out`` and the JIT cache (issue #14 item 11).

gmsh hands its GUI option defaults to FLTK even without a GUI, and FLTK's first look at its
options rewrites its preference files: ``$HOME/.fltk/fltk.org/fltk.prefs`` and, for root,
``/etc/fltk/fltk.org/fltk.prefs``. It happens once per process, at the first
``gmsh.initialize()``, so the mesh build runs in a fresh process here (``python -m fsi mesh``).
"""

import os
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import fsi

ROOT = Path(fsi.__file__).resolve().parent.parent
SYSTEM_PREFERENCES = Path("/etc/fltk/fltk.org/fltk.prefs")
MPI_LAUNCH = ("OMPI_", "PMIX_", "PMI_", "ORTE_")
KEEP = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM")


def fresh_process_env(home: Path) -> dict[str, str]:
    """This environment with ``HOME`` at ``home``, the JIT cache where it is now (reused, it is
    the one place a run may write besides ``--out``), and without the variables by which
    mpirun tells a process it is one of its ranks (the child is a serial run of its own)."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(MPI_LAUNCH) or k in KEEP}
    env["XDG_CACHE_HOME"] = os.environ.get("XDG_CACHE_HOME", str(Path.home() / ".cache"))
    env.pop("XDG_CONFIG_HOME", None)
    env["HOME"] = str(home)
    return env


def stat(path: Path) -> tuple | None:
    return (path.stat().st_mtime_ns, path.stat().st_size) if path.exists() else None


def test_a_mesh_build_writes_nothing_outside_out(shared_tmp):
    """``fsi mesh`` in a fresh process with an empty home folder and an empty current folder
    leaves both empty and the system's FLTK preferences untouched; the mesh is in --out."""
    comm = MPI.COMM_WORLD
    home, cwd, out = shared_tmp / "home", shared_tmp / "cwd", shared_tmp / "out"
    result = None
    if comm.rank == 0:  # one serial process is the test; the other ranks wait
        home.mkdir()
        cwd.mkdir()
        before = stat(SYSTEM_PREFERENCES)
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "fsi",
                "mesh",
                str(ROOT / "configs/channel_poiseuille.yaml"),
                "--out",
                str(out),
            ],
            cwd=cwd,
            env=fresh_process_env(home),
            capture_output=True,
            text=True,
            timeout=300,
        )
        result = (
            done.returncode,
            done.stderr,
            sorted(str(p) for p in home.rglob("*")),
            sorted(str(p) for p in cwd.rglob("*")),
            before,
            stat(SYSTEM_PREFERENCES),
            (out / "mesh.json").is_file(),
        )
    code, stderr, in_home, in_cwd, before, after, meshed = comm.bcast(result, root=0)
    assert code == 0, stderr
    assert meshed
    assert in_home == [] and in_cwd == []
    assert after == before
