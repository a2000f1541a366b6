"""The hemodynamic indices TAWSS, OSI and RRT (fsi.output.wall_indices.WallIndices, accumulated
in-run by fsi.output.wall_outputs.FluidOutputs; docs/hemodynamic-indices.md).

The accumulator against known answers on synthetic τ(t) (constant, sinusoidal over whole
periods, with uniform and non-uniform steps); ``fsi run`` on the straight channel against the
exact wall shear stress of Poiseuille flow (steady: TAWSS = (ΔP/L)(H/2), OSI = 0; purely
oscillating: OSI = ½, and the indices are the step-weighted sums of the exact τ(t_n) with the
schedule's true step sizes); wall_indices.csv's columns and units; a restarted run gives the
same indices as the uninterrupted one, and a stopped run has them too; on a moving mesh the
samples are reported at their reference coordinates.
"""

import csv
import json
import math
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from scipy.spatial import cKDTree

from fsi import cli, config
from fsi.geometry.tags import Boundary
from fsi.numerics.timestepping import steps
from fsi.output import io, wall_indices, wall_outputs
from fsi.run import errors, simulation, steppers

CHANNEL = "configs/channel_poiseuille.yaml"
L, H = 0.02, 0.007  # the channel (configs/channel_poiseuille.yaml)
MU = 0.0035
SERIAL = MPI.COMM_WORLD.size == 1


def fsi_run(case: str, out: Path, overrides, restart: Path | None = None) -> int:
    args = ["run", case, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
    return cli.main(args + ([] if restart is None else ["--restart", str(restart)]))


def read_indices(run: Path) -> tuple[list[str], list[dict]]:
    """wall_indices.csv's header and rows (numbers as floats, empty cells as NaN)."""
    with (run / "wall_indices.csv").open(newline="") as f:
        reader = csv.DictReader(f)
        rows = [
            {k: v if k in ("wall", "side") else float(v or "nan") for k, v in r.items()}
            for r in reader
        ]
        return reader.fieldnames, rows


def column(rows: list[dict], key: str) -> np.ndarray:
    return np.array([r[key] for r in rows])


# --------------------------------------------------------------------------------------------
# The accumulator on synthetic τ(t)


def accumulate(tau, dts, start: float = 0.0, interpolate: bool = True) -> wall_indices.WallIndices:
    """WallIndices of samples τ(t) (a function of t giving one value per sample) over steps of
    the sizes ``dts`` from t = 0, from the value τ(0)."""
    t = 0.0
    indices = wall_indices.WallIndices(len(tau(0.0)), start=start, interpolate=interpolate)
    indices.set_value(tau(0.0))
    for dt in dts:
        t += dt
        indices.add(t, tau(t))
    return indices


def test_constant_shear_has_tawss_its_magnitude_osi_zero_and_rrt_its_inverse():
    """Three samples under constant τ = 2, −3 and 0 Pa, steps of different sizes."""
    indices = accumulate(lambda t: np.array([2.0, -3.0, 0.0]), [0.1, 0.3, 0.05, 0.55])
    assert indices.duration == pytest.approx(1.0, rel=1e-15)
    assert indices.tawss == pytest.approx([2.0, 3.0, 0.0], rel=1e-14)
    # One sign throughout: |∫τ dt| and ∫|τ| dt are the same sums, so OSI is 0 exactly.
    assert indices.osi[:2].tolist() == [0.0, 0.0]
    assert np.isnan(indices.osi[2])  # no shear at all: undefined
    assert indices.rrt[:2] == pytest.approx([1 / 2.0, 1 / 3.0], rel=1e-14)
    assert indices.rrt[2] == np.inf


def oscillating(n: int, kind: str, interpolate: bool = True) -> wall_indices.WallIndices:
    """τ = (A sin(2πt/P), −A) over three whole periods in ``n`` steps, ``uniform`` or of
    ``random`` sizes in [0.5, 1.5] × the uniform one."""
    A, P = 3.0, 0.5
    if kind == "uniform":
        dts = np.full(n, 3 * P / n)
    else:
        sizes = np.random.default_rng(1).uniform(0.5, 1.5, n)
        dts = sizes / sizes.sum() * 3 * P
    return accumulate(
        lambda t: np.array([A * np.sin(2 * np.pi * t / P), -A]), dts, 0.0, interpolate
    )


@pytest.mark.parametrize("kind", ["uniform", "random"])
def test_purely_oscillating_shear_has_osi_one_half(kind):
    """τ = A sin(2πt/P) over three whole periods, 40 steps per period: OSI = ½ and TAWSS =
    2A/π. Uniform steps sum the sine to round-off (measured OSI − ½: 0; TAWSS −0.21 %, the
    linear interpolant of |sin|); steps of random sizes in [0.5, 1.5] × P/40 leave a
    second-order error (measured: OSI −6.0e-5, TAWSS −0.25 %; the rectangle rule with end
    values, what the indices used before: −8.2e-4 and +0.44 %)."""
    A = 3.0
    indices = oscillating(120, kind)
    osi, tawss = indices.osi[0], indices.tawss[0]
    assert osi == pytest.approx(0.5, abs=1e-12 if kind == "uniform" else 2e-4)
    assert tawss == pytest.approx(2 * A / np.pi, rel=5e-3)
    # The mean shear (nearly) cancels: RRT = 1/((1 − 2 OSI) TAWSS) is long.
    assert 1 / (indices.rrt[0] * tawss) == pytest.approx(1 - 2 * osi, abs=1e-12)
    assert indices.rrt[0] * tawss > 100
    assert (indices.tawss[1], indices.osi[1]) == (pytest.approx(A, rel=1e-14), 0.0)


def test_the_indices_are_second_order_in_uneven_steps():
    """Random steps, 120, 240 and 480 of them: the TAWSS error falls 4-fold per doubling
    (second order; measured 4.76e-3, 1.20e-3, 3.04e-4 of 2A/π), the OSI error is below the
    rectangle rule's (end values; measured 6.0e-5, 5.8e-6, 1.9e-6 against 8.2e-4, 2.8e-4,
    7.1e-5), whose TAWSS error is erratic (8.5e-3, 4.4e-4, 8.1e-4). A τ linear over each
    step, changing sign within it, is integrated exactly."""
    exact_tawss = 2 * 3.0 / np.pi

    def errors(n, interpolate):
        indices = oscillating(n, "random", interpolate)
        return abs(indices.tawss[0] - exact_tawss), abs(indices.osi[0] - 0.5)

    trapezoid = [errors(n, True) for n in (120, 240, 480)]
    rectangle = [errors(n, False) for n in (120, 240, 480)]
    for coarse, fine in zip(trapezoid, trapezoid[1:]):
        assert 3.5 < coarse[0] / fine[0] < 4.5, trapezoid
    assert all(t[1] < r[1] / 5 for t, r in zip(trapezoid, rectangle)), (trapezoid, rectangle)
    # τ from 3 to −1 over 0.4 s, then back to 1 over 0.6 s (a sign change in each step).
    indices = wall_indices.WallIndices(1)
    indices.set_value(np.array([3.0]))
    indices.add(0.4, np.array([-1.0]))
    indices.add(1.0, np.array([1.0]))
    # ∫ τ = 0.4 · 1 + 0.6 · 0; ∫ |τ| = 0.4 (9 + 1)/(2 · 4) + 0.6 (1 + 1)/(2 · 2)
    assert indices.integrals[0] == pytest.approx([0.4, 0.5 + 0.3], rel=1e-14)


def test_the_window_starts_at_start_and_a_step_across_it_counts_its_part_after_it():
    """Window from t = 1: the step to 0.5 counts for nothing, the step (0.5, 1.25] for its
    0.25 s after 1 (τ linear from 100 to 2: 34.67 at t = 1), (1.25, 2] wholly:
    TAWSS = (0.25 (34.67 + 2)/2 + 0.75 (2 + 4)/2) / 1. Without interpolation (steady runs)
    each step counts with its end value: (0.25·2 + 0.75·4) / 1."""
    for interpolate, expected in (
        (True, 0.25 * (100 - 98 * 0.5 / 0.75 + 2) / 2 + 2.25),
        (False, 3.5),
    ):
        indices = wall_indices.WallIndices(1, start=1.0, interpolate=interpolate)
        for t, tau in ((0.5, 100.0), (1.25, 2.0), (2.0, 4.0)):
            indices.add(t, np.array([tau]))
        assert indices.duration == pytest.approx(1.0, rel=1e-15)
        assert indices.tawss[0] == pytest.approx(expected, rel=1e-14)


def test_before_any_step_the_indices_are_undefined_and_steps_must_go_forward():
    indices = wall_indices.WallIndices(2)
    assert np.isnan(indices.tawss).all() and np.isnan(indices.osi).all()
    assert np.isnan(indices.rrt).all()
    indices.add(0.1, np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="must end after the last one"):
        indices.add(0.1, np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="expected 2 wall shear stresses"):
        indices.add(0.2, np.array([1.0]))


def test_state_continues_like_the_uninterrupted_accumulator():
    tau = lambda t: np.array([np.sin(7 * t), np.cos(3 * t) + 0.2])  # noqa: E731
    dts = [0.1, 0.2, 0.15, 0.3, 0.05]
    straight = accumulate(tau, dts)
    first = accumulate(tau, dts[:2])
    second = wall_indices.WallIndices(2)
    second.load_state(first.state())
    t = sum(dts[:2])
    second.set_value(tau(t))  # the restored solution's value (not in the state)
    for dt in dts[2:]:
        t += dt
        second.add(t, tau(t))
    for name in ("tawss", "osi", "rrt"):
        assert getattr(second, name).tolist() == getattr(straight, name).tolist(), name


def test_write_table_writes_nan_as_an_empty_cell_and_infinity_as_inf(shared_tmp):
    path = shared_tmp / "table.csv"
    io.write_table(
        MPI.COMM_WORLD,
        path,
        ["a", "b", "c", "d"],
        [["x", 1.0 / 3.0, math.nan, math.inf], ["y", 2, 0.5, -1e-30]],
    )
    assert path.read_text().splitlines() == ["a,b,c,d", "x,0.3333333333,,inf", "y,2,0.5,-1e-30"]
    assert not (shared_tmp / "table.csv.partial").exists()


# --------------------------------------------------------------------------------------------
# fsi run on the straight channel: Poiseuille flow


def pressure_channel(pressure: str, schedule: str, end: float) -> list[str]:
    """The channel driven by the inlet pressure P(t) (``pressure``, Pa) against the open
    outlet, solved steady at every step: Poiseuille flow with G = P(t)/L at every step (exact
    in P2/P1: test_open_boundaries), τ_w = G H/2 on both walls. Without the outlet's backflow
    term, which would change the traction where P < 0 drives the blood in through the outlet
    (the do-nothing form alone is exact for developed flow either way)."""
    return [
        "time.scheme=steady",
        f"time.schedule={schedule}",
        f"time.end={end}",
        f"fluid.inlet={{kind: pressure, formula: '{pressure}'}}",
        "fluid.outlet.backflow_stabilization=0",
    ]


def test_steady_poiseuille_has_the_exact_tawss_and_osi_zero(shared_tmp):
    """ΔP = 0.6 Pa over L = 2 cm (G = 30 Pa/m): TAWSS = G H/2 = 0.105 Pa at every sample of
    both walls (ends included: the open ends are exact for developed flow) within 1e-9
    relative (the Newton tolerance), OSI = 0 exactly, RRT = 1/TAWSS. The CSV: its columns,
    a row per sample (two per wall facet) sorted by wall, side and x, in metres and pascals."""
    out = shared_tmp / "steady"
    assert fsi_run(CHANNEL, out, pressure_channel("0.6", "[{until: 0.003, dt: 0.001}]", 0.003)) == 0
    header, rows = read_indices(out)
    assert header == ["wall", "side", "x", "y", "TAWSS", "OSI", "RRT"]
    exact = 30.0 * H / 2
    assert column(rows, "TAWSS") == pytest.approx(exact, rel=1e-9)
    assert column(rows, "OSI").tolist() == [0.0] * len(rows)
    assert column(rows, "RRT") == pytest.approx(1 / exact, rel=1e-9)
    # Units and placement: x in [0, L] (m) along the lower (y = 0) and upper (y = H) walls.
    assert {r["wall"] for r in rows} == {"rigid_wall"}
    x, y = column(rows, "x"), column(rows, "y")
    assert (0 < x).all() and (x < L).all()
    lower = np.array([r["side"] == "lower" for r in rows])
    assert np.abs(y[lower]).max() < 1e-12 and np.abs(y[~lower] - H).max() < 1e-12
    assert [r["side"] for r in rows] == sorted(r["side"] for r in rows)
    assert (np.diff(x[lower]) > 0).all() and (np.diff(x[~lower]) > 0).all()
    assert lower.sum() == (~lower).sum() == 2 * round(L / 5e-4)  # two per 0.5 mm facet
    summary = json.loads((out / "summary.json").read_text())
    assert summary["min_tawss"] == pytest.approx(exact, rel=1e-9)
    assert summary["max_osi"] == 0.0
    assert summary["max_rrt"] == pytest.approx(1 / exact, rel=1e-9)


def test_oscillating_poiseuille_has_osi_one_half_with_the_true_step_sizes(shared_tmp):
    """P(t) = 0.6 sin(2πt/0.01) Pa over two periods, 16 steps of 0.625 ms in the first and 8
    of 1.25 ms in the second: each step is Poiseuille flow with τ_n = P(t_n) H/(2L), so the
    indices are the step-weighted sums TAWSS = Σ |τ_n| Δt_n / T and OSI = ½ (1 − |Σ τ_n Δt_n|
    / Σ |τ_n| Δt_n) over the schedule's true steps (to 1e-9 of their scale; the coarser
    second period samples |sin| less well, so its weight shows in TAWSS), and OSI = ½: each
    period's equal steps sum the sine to zero."""
    out = shared_tmp / "oscillating"
    pressure = "0.6 * sin(2 * pi * t / 0.01)"
    overrides = pressure_channel(
        pressure, "[{until: 0.01, dt: 0.000625}, {until: 0.02, dt: 0.00125}]", 0.02
    )
    assert fsi_run(CHANNEL, out, overrides) == 0
    schedule = list(steps(config.load(CHANNEL, overrides).time))
    t = np.array([s.t for s in schedule])
    dt = np.array([s.dt for s in schedule])
    assert len(t) == 16 + 8 and dt.sum() == pytest.approx(0.02, rel=1e-14)
    tau = 0.6 * np.sin(2 * np.pi * t / 0.01) * H / (2 * L)
    magnitude, mean = (np.abs(tau) * dt).sum(), abs((tau * dt).sum())
    by_sample = np.abs(tau).mean()  # an average over the samples instead of over time
    assert abs(magnitude / dt.sum() - by_sample) > 5e-3 * by_sample
    _, rows = read_indices(out)
    assert column(rows, "TAWSS") == pytest.approx(magnitude / dt.sum(), rel=1e-9)
    assert np.abs(column(rows, "OSI") - 0.5).max() < 1e-9
    # RRT = T/|Σ τ Δt|: huge where the mean shear cancels; its inverse within 1e-9 of the
    # scale T/Σ|τ|Δt of the cancelled sum.
    assert np.abs(1 / column(rows, "RRT") - mean / dt.sum()).max() < 1e-9 * magnitude / dt.sum()


# --------------------------------------------------------------------------------------------
# Restarts and stopped runs


RESTART_SET = ["time.schedule=[{until: 0.004, dt: 0.001}]"]  # from rest, the default pulse


@pytest.fixture(scope="module")
def channel_runs():
    """The channel under the study's inlet pulse (BDF2 from rest): 4 steps straight; 2 steps,
    then a restart in the same folder up to step 4; 4 steps stopped (as by SIGUSR1) after
    step 2."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    straight, split, stopped = path / "straight", path / "split", path / "stopped"
    codes = [
        fsi_run(CHANNEL, straight, [*RESTART_SET, "time.end=0.004"]),
        fsi_run(CHANNEL, split, [*RESTART_SET, "time.end=0.002"]),
    ]
    first = read_indices(split)[1]
    codes.append(fsi_run(CHANNEL, split, [*RESTART_SET, "time.end=0.004"], restart=split))
    polls = []

    def stop_after_step_2():
        polls.append(1)
        return 10 if len(polls) == 2 else None

    case = config.load(CHANNEL, [*RESTART_SET, "time.end=0.004"])
    with pytest.raises(errors.Interrupted) as stop:
        simulation.run(case, stopped, comm, stop_requested=stop_after_step_2)
    yield {
        "codes": codes,
        "straight": straight,
        "split": split,
        "stopped": stopped,
        "first": first,
        "stopped_at": stop.value.step,
    }
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def assert_same_indices(a: list[dict], b: list[dict]) -> None:
    assert [(r["wall"], r["side"]) for r in a] == [(r["wall"], r["side"]) for r in b]
    for key in ("x", "y", "TAWSS", "OSI", "RRT"):
        if SERIAL:  # bit for bit (as the restart's other state, tests/test_restart.py)
            assert column(a, key).tolist() == column(b, key).tolist(), key
        else:  # another mesh partition: round-off
            assert column(a, key) == pytest.approx(column(b, key), rel=1e-9, abs=1e-15), key


def test_a_restarted_run_has_the_indices_of_the_uninterrupted_run(channel_runs):
    assert channel_runs["codes"] == [0, 0, 0]
    straight = read_indices(channel_runs["straight"])[1]
    assert_same_indices(read_indices(channel_runs["split"])[1], straight)
    # The pulse drives the flow forward along both walls: no reversal yet, and the indices
    # of the first two steps (written with that segment's checkpoint) differ from the four's.
    assert (column(straight, "TAWSS") > 0).all() and (column(straight, "OSI") == 0).all()
    first = channel_runs["first"]
    assert not np.allclose(column(first, "TAWSS"), column(straight, "TAWSS"))


def test_a_stopped_run_has_the_indices_of_its_checkpoint(channel_runs):
    """Stopped after step 2: its checkpoint and wall_indices.csv are step 2's, the same as the
    2-step run's."""
    assert channel_runs["stopped_at"] == 2
    assert_same_indices(read_indices(channel_runs["stopped"])[1], channel_runs["first"])


def test_a_checkpoint_written_before_the_indices_existed_restarts_them_from_its_time(
    channel_runs, shared_tmp, fsi_log
):
    """A checkpoint of an earlier version has no ``wall_indices.*`` arrays (nor their keys):
    the restart goes on, with a warning, and averages from the restart's time only, so the
    indices of steps 3–4 equal those of the uninterrupted run's steps 3–4 alone."""
    comm = MPI.COMM_WORLD
    old = shared_tmp / "old"
    if comm.rank == 0:
        shutil.copytree(channel_runs["split"], old)
        shutil.rmtree(old / "checkpoint")
        shutil.copytree(channel_runs["stopped"] / "checkpoint", old / "checkpoint")  # step 2
        shutil.copy(channel_runs["stopped"] / "metrics.csv", old / "metrics.csv")
        for rank_file in (old / "checkpoint").glob("rank*.npz"):
            with np.load(rank_file) as data:
                arrays = {
                    k: data[k]
                    for k in data.files
                    if not k.startswith(("wall_indices.", "keys.wall_samples"))
                }
            with rank_file.open("wb") as f:
                np.savez(f, **arrays)
    comm.barrier()
    assert fsi_run(CHANNEL, old, [*RESTART_SET, "time.end=0.004"], restart=old) == 0
    if comm.rank == 0:
        assert "holds no wall shear stress indices" in fsi_log.text
    restarted = read_indices(old)[1]
    straight, first = read_indices(channel_runs["straight"])[1], channel_runs["first"]
    # ∫ over steps 3–4 = ∫ over 1–4 − ∫ over 1–2, in TAWSS·T with T = 2 ms each part.
    later = (4 * column(straight, "TAWSS") - 2 * column(first, "TAWSS")) / 2
    assert column(restarted, "TAWSS") == pytest.approx(later, rel=1e-6)


# --------------------------------------------------------------------------------------------
# A moving wall: samples at their reference coordinates


def test_moving_wall_samples_keep_their_reference_coordinates(shared_tmp):
    """The coupled moving-wall stenosis after one step: the interface's samples have moved with
    the wall, the state and wall_indices.csv give each at its reference coordinates (where it
    was when the stepper was built), and the summary has the lumen's extremes."""
    comm = MPI.COMM_WORLD
    case = config.load(
        "configs/stenosis_moving_newtonian.yaml",
        ["time.schedule=[{until: 0.001, dt: 0.001}]", "time.end=0.001"],
    )
    stepper = steppers.CoupledStepper(case, comm)
    outputs = stepper.outputs
    reference = outputs.sampler.reference.copy()
    interface = outputs.sampler.walls == Boundary.INTERFACE
    stepper.step(next(iter(steps(case.time))))
    moved = np.linalg.norm(outputs.sampler.local().x - reference, axis=1)
    assert comm.allreduce(float(moved[interface].max(initial=0.0)), op=MPI.MAX) > 1e-7
    assert comm.allreduce(float(moved[~interface].max(initial=0.0)), op=MPI.MAX) == 0.0
    state = stepper.state()
    assert np.array_equal(state["wall_indices.points"], reference)
    assert state["wall_indices.window"].tolist() == [0.001, 0.001]
    wall_outputs.FluidOutputs.write_indices(shared_tmp, comm, state)
    _, rows = read_indices(shared_tmp)
    written = np.column_stack([column(rows, "x"), column(rows, "y")])
    everywhere = np.concatenate(comm.allgather(reference))
    assert len(written) == len(everywhere)
    distance, match = cKDTree(everywhere).query(written)  # the CSV keeps 10 digits
    assert distance.max() < 1e-10 and len(set(match)) == len(written)
    assert {(r["wall"], r["side"]) for r in rows} == {
        ("interface", "lower"),
        ("rigid_wall", "upper"),
    }
    summary = stepper.summary()
    assert summary["min_tawss"] > 0 and 0 <= summary["max_osi"] <= 0.5
    assert summary["max_rrt"] >= 1 / max(column(rows, "TAWSS"))
