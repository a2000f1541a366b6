"""scripts/benchmark_study.py (docs/performance.md): its runs are fsi run's own loop in their own
processes, and its tables add up. Two coarse steps on 1 and 2 ranks, coupled and rigid."""

import json
import os
import subprocess
import sys
from pathlib import Path

from mpi4py import MPI

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "benchmark_study.py"

pytestmark = pytest.mark.skipif(
    MPI.COMM_WORLD.size > 1, reason="launches its own processes; runs in the serial lane"
)


def test_a_failed_run_says_why_not_how_mpi_aborted():
    """The worker's exception, not Open MPI's MPI_ABORT notice that follows it."""
    from fsi.performance.study_speed import why_failed

    output = "\n".join(
        [
            "Traceback (most recent call last):",
            '  File "x.py", line 1, in <module>',
            "fsi.config.reader.ConfigError: case.yaml: time.end: expected a number, got 'x'",
            "-" * 74,
            "MPI_ABORT was invoked on rank 0 in communicator MPI_COMM_WORLD",
            "with errorcode 1.",
            "NOTE: invoking MPI_ABORT causes Open MPI to kill all MPI processes.",
        ]
    )
    assert why_failed(output) == (
        "fsi.config.reader.ConfigError: case.yaml: time.end: expected a number, got 'x'"
    )
    assert why_failed("one\ntwo") == "one | two"


@pytest.fixture(scope="module")
def benchmark(tmp_path_factory):
    target = tmp_path_factory.mktemp("bench") / "runs.json"
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--levels", "coarse", "--steps", "coarse=3"]
        + ["--ranks", "1", "2", "--json", str(target)],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "OMPI_MCA_btl_vader_single_copy_mechanism": "none"},
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout, json.loads(target.read_text())


def test_every_run_finishes_its_steps(benchmark):
    _, runs = benchmark
    assert {(r["mode"], r["ranks"]) for r in runs} == {
        ("coupled", 1),
        ("rigid", 1),
        ("coupled", 2),
        ("rigid", 2),
    }
    for r in runs:
        assert not r["failure"] and r["steps"] == 3, r
        assert r["s_per_step"] > 0 and len(r["memory_mb"]) == r["ranks"]


def test_the_coupled_run_is_the_coupled_problem(benchmark):
    _, runs = benchmark
    for r in runs:
        iterations = r["coupling_iterations"]
        if r["mode"] == "coupled":
            assert (
                len(iterations) == 3 and min(iterations) >= 2
            )  # the pulse: never converged at once
            assert r["summary"]["solid_dofs"] > 0
        else:
            assert "solid_dofs" not in r["summary"]


def test_the_time_split_is_within_the_step(benchmark):
    """The profiled pieces are exclusive times, so on each rank they add up to at most the
    step's time, and the fluid, the structure and the output each took some."""
    _, runs = benchmark
    for r in runs:
        pieces = r["profile_ms"]
        assert 0 < r["profiled_ms"] <= r["step_ms"] * 1.001
        assert r["profiled_ms"] <= sum(pieces.values()) * 1.001  # a sum of per-piece maxima
        if r["mode"] == "coupled":
            for key in ("fluid LU factorisation", "solid residual assembly", "output: fields"):
                assert pieces[key] > 0, key


def test_the_tables_show_ratio_speed_up_and_split(benchmark):
    out, runs = benchmark
    by = {(r["mode"], r["ranks"]): r for r in runs}
    ratio = by[("coupled", 1)]["s_per_step"] / by[("rigid", 1)]["s_per_step"]
    row = next(line for line in out.splitlines() if line.startswith("coarse       1 "))
    assert f"{ratio:.2f}" in row.split()
    assert "2-rank speed-up" in out and "Where a coupled step's time goes" in out
