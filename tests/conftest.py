"""Shared fixtures. The suite runs serially and under ``mpirun -n 2 python -m mpi4py -m pytest``."""

import gc
import logging
import os
import shutil
import sys
import tempfile
import time
import zlib
from pathlib import Path

# pytest-xdist (the serial lane of scripts/test runs on two workers) starts its workers with the
# environment its controller has after MPI_Init: the controller's MPI singleton (Open MPI's PMIx
# server address and the like), under which an mpirun started by a test takes itself for part of
# that job and fails. The controller records the names it had before MPI started, and a worker
# drops every other name but pytest's own.
_NAMES_BEFORE_MPI = "FSI_TEST_ENVIRONMENT"
if "PYTEST_XDIST_WORKER" in os.environ and _NAMES_BEFORE_MPI in os.environ:
    _kept = set(os.environ[_NAMES_BEFORE_MPI].split(","))
    for _name in list(os.environ):
        if _name not in _kept and not _name.startswith("PYTEST_"):
            del os.environ[_name]
else:
    os.environ[_NAMES_BEFORE_MPI] = ",".join(os.environ)

from mpi4py import MPI
from petsc4py import PETSc

import numpy as np
import pytest


@pytest.fixture(autouse=True)
def _collect_and_sync():
    """Free PETSc/dolfinx objects and line the ranks up after every test (as dolfinx does).
    petsc4py only stashes a collected parallel object (its destruction is collective, and the
    ranks collect at different moments): ``garbage_cleanup`` destroys them on every rank at
    once, or they would pile up for the whole 2-rank run."""
    yield
    gc.collect()
    PETSc.garbage_cleanup(MPI.COMM_WORLD)
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


# --------------------------------------------------------------------------------------------
# On several ranks: the ranks must agree on every test's outcome.
#
# A test that fails on one rank only leaves the ranks out of step: the other rank's pending
# collectives (a broadcast, a barrier) are matched with the wrong calls in later tests, and the
# lane hangs, or fails far from the cause, until the lane's timeout. After every test the ranks
# compare which test they ran and whether it failed, on a communicator of their own and with a
# deadline; when they disagree, or a rank does not arrive, the failing rank's report is printed
# and the run is aborted at once.

_RANKS = MPI.COMM_WORLD.Dup() if MPI.COMM_WORLD.size > 1 else None
_WAIT = float(os.environ.get("FSI_TEST_RANK_WAIT", "600"))
"""Seconds a rank that has finished a test waits for the others to finish it."""
_FAILURES = pytest.StashKey[list]()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    report = (yield).get_result()
    if report.failed:
        item.stash.setdefault(_FAILURES, []).append(f"{report.when}: {report.longreprtext}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    yield
    if _RANKS is not None:
        _ranks_agree(item)


def _ranks_agree(item: pytest.Item) -> None:
    failures = item.stash.get(_FAILURES, [])
    mine = np.array([zlib.crc32(item.nodeid.encode()), bool(failures)], dtype=np.int64)
    everyone = np.empty((_RANKS.size, 2), dtype=np.int64)
    request = _RANKS.Iallgather(mine, everyone)
    deadline = time.monotonic() + _WAIT
    while not request.Test():
        if time.monotonic() > deadline:
            _abort(item, failures, f"the other ranks have not finished it after {_WAIT:g} s")
        time.sleep(0.005)
    if len(set(everyone[:, 0])) > 1:
        _abort(item, failures, "the ranks ran different tests")
    failed = [rank for rank, flag in enumerate(everyone[:, 1]) if flag]
    if failed and len(failed) < _RANKS.size:
        _abort(item, failures, f"it failed on rank(s) {failed} only: the ranks are out of step")


def _abort(item: pytest.Item, failures: list[str], why: str) -> None:
    capture = item.config.pluginmanager.getplugin("capturemanager")
    with capture.global_and_fixture_disabled():
        rank = _RANKS.rank
        state = "failed" if failures else "passed"
        print(f"\nrank {rank}: {item.nodeid} {state}; {why}. Aborting.", file=sys.stderr)
        for text in failures:
            print(f"rank {rank}: {text}", file=sys.stderr)
        sys.stderr.flush()
        sys.stdout.flush()
    MPI.COMM_WORLD.Abort(3)
