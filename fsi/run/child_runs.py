"""``fsi run`` in a child process, as the studies and benchmarks that compare whole runs make them
(fsi/study/models.py, fsi/benchmarks/concentric_3d.py, fsi/performance/accuracy.py): the
command, on one rank or under ``mpirun``, in an environment its ``mpirun`` accepts (also that of
fsi/study/reproduce.py's runs and fsi/performance/study_speed.py's workers), and a finished run
kept when asked to reuse it."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def command(config: Path, out: Path, overrides: Sequence[str], ranks: int = 1) -> list[str]:
    """``fsi run CONFIG --out OUT --overwrite --set ...`` with this Python, under ``mpirun -n
    RANKS`` when ``ranks`` > 1."""
    line = [sys.executable, "-m", "fsi", "run", str(config), "--out", str(out), "--overwrite"]
    line += [a for o in overrides for a in ("--set", o)]
    return ["mpirun", "-n", str(ranks), *line] if ranks > 1 else line


SINGLE_COPY = "OMPI_MCA_btl_vader_single_copy_mechanism"
"""Open MPI's shared-memory single-copy transfers (CMA), which containers and chroots often lack
the kernel support for (scripts/test sets it for the test lanes): ``none`` unless set."""


def environment() -> dict[str, str]:
    """The environment of a child ``fsi run`` (or ``mpirun``) launched by a process that may
    already have run MPI_Init (mpi4py, imported with fsi): Python's copy of the environment, not
    the one MPI_Init has since changed (which would make a child's ``mpirun`` take itself for a
    singleton's child); Open MPI's permission to run as root when this is root; and the
    single-copy transfers off (:data:`SINGLE_COPY`) unless the environment chooses. The one
    child environment of the study's reruns (fsi/study/reproduce.py), the speed study's workers
    (fsi/performance/study_speed.py) and :func:`run`."""
    env = dict(os.environ)
    if os.geteuid() == 0:
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    env.setdefault(SINGLE_COPY, "none")
    return env


def run(
    config: Path, out: Path, overrides: Sequence[str], ranks: int = 1, reuse: bool = False
) -> Path:
    """The run folder ``out`` of ``config`` with ``overrides``, made by ``fsi run`` (its standard
    output discarded, its messages on standard error) unless ``reuse`` finds it finished (its
    summary.json, which ``fsi run`` writes at the end). Raises CalledProcessError if it fails."""
    if reuse and (out / "summary.json").is_file():
        return out
    line = command(config, out, overrides, ranks)
    print("$", " ".join(line), flush=True)
    subprocess.run(line, cwd=ROOT, check=True, stdout=subprocess.DEVNULL, env=environment())
    return out
