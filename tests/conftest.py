"""Shared fixtures. The suite runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``."""

import gc
from pathlib import Path

from mpi4py import MPI

import pytest


@pytest.fixture(autouse=True)
def _collect_and_sync():
    """Free PETSc/dolfinx objects and line the ranks up after every test (as dolfinx does)."""
    yield
    gc.collect()
    MPI.COMM_WORLD.barrier()


@pytest.fixture
def comm() -> MPI.Comm:
    return MPI.COMM_WORLD


@pytest.fixture
def shared_tmp(tmp_path: Path) -> Path:
    """A temporary folder that is the same on every rank (rank 0's)."""
    return Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0))
