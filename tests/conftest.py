"""Shared fixtures. The suite runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``."""

import gc
import logging
import shutil
import tempfile
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
def shared_tmp():
    """A temporary folder that is the same on every rank. Not pytest's ``tmp_path``: each rank's
    pytest rotates its own numbered base folders and may delete the one rank 0 handed out."""
    comm = MPI.COMM_WORLD
    path = tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None
    path = Path(comm.bcast(path, root=0))
    yield path
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture
def fsi_log(caplog):
    """The 'fsi' logger does not propagate to the root: hand its records to caplog too."""
    logger = logging.getLogger("fsi")
    logger.addHandler(caplog.handler)
    yield caplog
    logger.removeHandler(caplog.handler)
