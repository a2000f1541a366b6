"""The shipped solver settings of the study's cases leave the answer where the tolerances put it
(docs/performance.md).

The speed settings of the stenosis configs (the cubic interface predictor, IQN-ILS keeping
8 steps' columns, the fluid's and the structure's Jacobians kept across iterations and steps
while they contract the residual (the fluid's while an iteration leaves at most 0.7 of it),
dropped at every periodic checkpoint, and the forced fluid solves of the later coupling
iterations, ``coupling.fluid_forcing``) change the path of every step, not the problem: the
answer may move only as far as the coupling and Newton tolerances let it. The reference is the
same case solved far tighter (coupling 1e-8 instead of 1e-6, Newton atol 1e-12, a fresh
Jacobian at every iteration, the linear predictor, no columns of earlier steps, no forcing):
the headline columns of metrics.csv over the pulse (the first 40 steps, where the coupling works
hardest) must agree with it to 5e-4 of each column's peak.

Measured on the coarse mesh (relative to the peak, the largest over the 40 steps; all in the
mean outlet pressure): the shipped settings 5.8e-5 (1.0e-4 with the quadratic predictor shipped
before); the same without forcing 1.7e-4; the settings before #11 (linear predictor, 4 steps'
columns, Jacobians kept within a step only and renewed at 0.3) 2.1e-4. Over the whole heartbeat
the largest differences are of the same size (shipped 8.6e-5, quadratic 1.5e-4, in the
recirculation length at 4 ms, which jumps by facets). The bound leaves room for the 2-rank
partition and dolfinx 0.9; CONTROL below, a coupling loosened to 3e-4, is 1.1e-3 off and caught
(to 1e-4 it was 3.6e-3 off with the quadratic predictor, but only 3.8e-4 with the cubic one,
which starts each step nearer the answer). Coupling iterations per step over these steps:
shipped 3.55 (quadratic 3.70), without forcing 3.53, before #11 3.93, the tight solve 7.3; fluid
Newton iterations over the 40 steps: shipped 451, without forcing 646.
"""

import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import pytest

from fsi import cli
from fsi.output import metrics_csv
from fsi.performance.comparison import largest_differences

CASE = "configs/stenosis_moving_carreau.yaml"
PULSE = ["time.end=0.01"]  # 40 steps of 0.25 ms: the 5 ms pulse and the 5 ms after it
TIGHT = [
    "coupling.tolerance=1e-8",
    "coupling.predictor=linear",
    "coupling.iqn_reuse=0",
    "coupling.fluid_forcing=0",
    "fluid.solver.atol=1e-12",
    "fluid.solver.jacobian_reuse=none",
    "structure.solver.atol=1e-12",
    "structure.solver.jacobian_reuse=none",
]
BOUND = 5e-4


def pulse(out, overrides) -> list[dict]:
    args = ["run", CASE, "--out", str(out), "--set", "output.fields_every=1000"]
    assert cli.main([*args, *sum((["--set", s] for s in [*PULSE, *overrides]), [])]) == 0
    return metrics_csv.read_metrics(out / "metrics.csv")


PREVIOUS = [  # the settings before #11
    "coupling.predictor=linear",
    "coupling.iqn_reuse=4",
    "fluid.solver.jacobian_reuse=step",
    "fluid.solver.jacobian_reuse_rate=0.3",
    "structure.solver.jacobian_reuse=step",
    "coupling.fluid_forcing=0",
]
UNFORCED = ["coupling.fluid_forcing=0"]  # the shipped settings, each fluid solve to its tolerance
CONTROL = ["coupling.tolerance=3e-4"]


@pytest.fixture(scope="module")
def runs():
    """The four runs, in one folder that is the same on every rank (pytest's tmp folders are
    per rank)."""
    comm = MPI.COMM_WORLD
    folder = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    named = {
        "shipped": [],
        "tight": TIGHT,
        "previous": PREVIOUS,
        "unforced": UNFORCED,
        "control": CONTROL,
    }
    yield {name: pulse(folder / name, overrides) for name, overrides in named.items()}
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(folder, ignore_errors=True)


def worst_difference(rows: list[dict], reference: list[dict]) -> dict[str, float]:
    """Per headline column (fsi/performance/comparison.py), max |rows − reference| over the steps /
    max |reference|."""
    assert len(rows) == len(reference) == 40
    return largest_differences(rows, reference)


@pytest.mark.parametrize("name", ["shipped", "previous", "unforced"])
def test_settings_agree_with_a_tight_solve(runs, name):
    difference = worst_difference(runs[name], runs["tight"])
    assert max(difference.values()) <= BOUND, difference


def test_the_bound_catches_a_loose_coupling(runs):
    difference = worst_difference(runs["control"], runs["tight"])
    assert max(difference.values()) > BOUND, difference


def test_shipped_settings_take_fewer_coupling_iterations(runs):
    """What the settings are for: fewer coupling iterations per step than before, at the same
    tolerance."""
    mean = {
        name: sum(r["coupling_iterations"] for r in runs[name]) / 40
        for name in ("shipped", "previous")
    }
    assert mean["shipped"] < mean["previous"], mean


def test_forced_fluid_solves_take_fewer_newton_iterations(runs):
    """What ``coupling.fluid_forcing`` is for: fewer fluid Newton iterations per step than
    solving every coupling iteration's fluid step to the Newton tolerance, at the same answer
    (test_settings_agree_with_a_tight_solve)."""
    total = {
        name: sum(r["newton_iterations"] for r in runs[name]) for name in ("shipped", "unforced")
    }
    assert total["shipped"] < 0.9 * total["unforced"], total
