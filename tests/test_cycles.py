"""Heartbeats: ``time.cycles`` (the schedule of one heartbeat repeated, fsi.config.Time), the
``cycle`` column of metrics.csv, the wall indices per heartbeat (wall_indices.csv's ``cycle``
column, reset at every heartbeat, continued across restarts), summary.json's ``cycles`` table
and ``fsi report``'s heartbeat table; the ``mean_inlet_pressure``/``mean_outlet_pressure``
columns; the location of the cap's largest principal stress (``max_principal_cap_x``/``_y``).

The runs are the straight channel (configs/channel_poiseuille.yaml) driven by a small periodic
pulse read from a CSV file, 4 steps per heartbeat, and one structure step of the coarse
stenosis.
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

from fsi import cli, compat, config
from fsi.config.run_size import count_steps
from fsi.geometry.tags import Region
from fsi.numerics.timestepping import steps
from fsi.output import report, report_runs
from fsi.physics import fluid_boundaries, mesh
from fsi.run import errors, outputs, simulation, steppers

CHANNEL = "configs/channel_poiseuille.yaml"
L, H = 0.02, 0.007  # the channel (configs/channel_poiseuille.yaml)
PERIOD = 0.004
SERIAL = MPI.COMM_WORLD.size == 1


def pulse_csv() -> str:
    """A pulse.csv-like waveform of period 4 ms: P = 0.1 + 0.25 (1 − cos 2πt/T) Pa, every
    0.5 ms (Pa-sized so that the channel's flow stays slow and laminar)."""
    t = np.linspace(0.0, PERIOD, 9)
    p = 0.1 + 0.25 * (1 - np.cos(2 * np.pi * t / PERIOD))
    return "t,P\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(t, p, strict=True))


def pulse_inlet(folder: Path) -> str:
    return f"fluid.inlet={{kind: pressure_file, file: '{folder / 'pulse.csv'}', period: {PERIOD}}}"


def cycles_set(folder: Path, cycles: int = 2, steady: bool = True) -> list[str]:
    """``cycles`` heartbeats of the pulse, one heartbeat's schedule (4 steps of 1 ms) and
    ``time.end`` one heartbeat (the case file's view); ``steady``: every step is Poiseuille
    flow for P(t_n) (exact in P2/P1), so the flow is periodic from the first heartbeat on.
    No outlet backflow term (as tests/test_wall_indices.py: the do-nothing outlet is exact)."""
    return [
        pulse_inlet(folder),
        f"time.cycles={cycles}",
        f"time.end={PERIOD}",
        f"time.schedule=[{{until: {PERIOD}, dt: 0.001}}]",
        "fluid.outlet.backflow_stabilization=0",
        *(["time.scheme=steady"] if steady else []),
    ]


def fsi_run(out: Path, overrides, restart: Path | None = None) -> int:
    args = ["run", CHANNEL, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
    return cli.main(args + ([] if restart is None else ["--restart", str(restart)]))


def read_csv(path: Path) -> tuple[list[str], list[dict]]:
    """A CSV's header and rows (numbers as floats, text kept, empty cells as NaN)."""

    def value(text: str):
        try:
            return float(text or "nan")
        except ValueError:
            return text

    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, [{k: value(v) for k, v in r.items()} for r in reader]


def column(rows: list[dict], key: str) -> np.ndarray:
    return np.array([r[key] for r in rows])


@pytest.fixture(scope="module")
def runs():
    """Two heartbeats of the pulse: ``steady`` (periodic at once); ``bdf2`` from rest, straight;
    ``split``, the same stopped (as by SIGUSR1) after step 6, in the middle of heartbeat 2,
    then restarted in its folder."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    if comm.rank == 0:
        (path / "pulse.csv").write_text(pulse_csv())
    comm.barrier()
    folders = {name: path / name for name in ("steady", "bdf2", "split")}
    codes = [
        fsi_run(folders["steady"], cycles_set(path)),
        fsi_run(folders["bdf2"], cycles_set(path, steady=False)),
    ]
    polls = []

    def stop_after_step_6():
        polls.append(1)
        return 10 if len(polls) == 6 else None

    case = config.load(CHANNEL, cycles_set(path, steady=False))
    with pytest.raises(errors.Interrupted) as stop:
        simulation.run(case, folders["split"], comm, stop_requested=stop_after_step_6)
    stopped = read_csv(folders["split"] / "wall_indices.csv")[1]
    codes.append(
        fsi_run(folders["split"], cycles_set(path, steady=False), restart=folders["split"])
    )
    yield {
        "path": path,
        "codes": codes,
        "stopped_at": stop.value.step,
        "stopped_indices": stopped,
        **folders,
    }
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


# --------------------------------------------------------------------------------------------
# time.cycles


def test_the_schedule_of_one_heartbeat_is_repeated_to_cycles_times_the_period():
    """A schedule whose second segment runs past the period is cut at T; each heartbeat has the
    same steps, shifted by T, and ends exactly on k T; without cycles the schedule is kept."""
    time = config.Time(
        end=0.01,
        cycles=3,
        schedule=(config.TimeSegment(0.004, 0.002), config.TimeSegment(0.05, 0.003)),
    )
    run = time.run_schedule(0.01)
    assert run.end == pytest.approx(0.03, rel=1e-15) and run.cycles == 0
    walked = list(steps(run))
    assert [s.index for s in walked] == list(range(1, 13))
    assert count_steps(run) == 12
    for k in range(3):
        beat = walked[4 * k : 4 * k + 4]
        assert [s.t - k * 0.01 for s in beat] == pytest.approx(
            [0.002, 0.004, 0.007, 0.01], rel=1e-12
        )
        assert beat[-1].t == (k + 1) * 0.01  # exactly: the heartbeat's last step ends on k T
    assert time.run_schedule(0.0) is time
    assert config.Time(end=0.01).run_schedule(0.01) == config.Time(end=0.01)


def test_cycles_runs_the_heartbeats_with_a_cycle_column(runs):
    assert runs["codes"] == [0, 0, 0]
    header, rows = read_csv(runs["steady"] / "metrics.csv")
    assert header[:4] == ["step", "t", "dt", "cycle"]
    assert column(rows, "cycle").tolist() == [1, 1, 1, 1, 2, 2, 2, 2]
    assert column(rows, "t") == pytest.approx([0.001 * n for n in range(1, 9)], rel=1e-12)
    assert rows[-1]["t"] == pytest.approx(2 * PERIOD, rel=1e-15)
    summary = json.loads((runs["steady"] / "summary.json").read_text())
    assert summary["end_time_s"] == pytest.approx(2 * PERIOD, rel=1e-15)
    saved = config.load(runs["steady"] / "config.yaml")  # the resolved case loads again
    assert (saved.time.cycles, saved.time.end) == (2, PERIOD)


def test_a_steady_periodic_flow_has_equal_indices_in_every_heartbeat(runs):
    """Every step is Poiseuille flow for P(t_n): τ_n = P(t_n) H / (2 L) on both walls, so each
    heartbeat's TAWSS is Σ |τ_n| Δt / T over its own 4 steps (the accumulators start afresh at
    T), the same in both heartbeats, OSI = 0; summary.json's ``cycles`` say the solution is
    periodic (changes at round-off)."""
    header, rows = read_csv(runs["steady"] / "wall_indices.csv")
    assert header == ["cycle", "wall", "side", "x", "y", "TAWSS", "OSI", "RRT"]
    case = config.load(CHANNEL, cycles_set(runs["path"]))
    pressure = fluid_boundaries.inlet_pressure(case.fluid.inlet)
    tau = np.array([pressure(0.001 * n) for n in range(1, 5)]) * H / (2 * L)
    exact = np.abs(tau).mean()
    first = [r for r in rows if r["cycle"] == 1]
    second = [r for r in rows if r["cycle"] == 2]
    assert len(first) == len(second) == len(rows) / 2 == 4 * round(L / 5e-4)
    for beat in (first, second):
        assert column(beat, "TAWSS") == pytest.approx(exact, rel=1e-9)
        assert column(beat, "OSI").tolist() == [0.0] * len(beat)
    assert column(second, "TAWSS") == pytest.approx(column(first, "TAWSS"), rel=1e-12)
    assert column(second, "x").tolist() == column(first, "x").tolist()

    summary = json.loads((runs["steady"] / "summary.json").read_text())
    beats = summary["cycles"]
    assert [b["cycle"] for b in beats] == [1, 2] and all(b["complete"] for b in beats)
    assert [b["steps"] for b in beats] == [4, 4]
    assert [b["start_s"] for b in beats] == pytest.approx([0.0, PERIOD], rel=1e-15)
    assert beats[0]["max_change"] is None and beats[1]["max_change"] < 1e-9
    assert beats[1]["values"]["min_tawss"] == pytest.approx(exact, rel=1e-9)
    assert beats[1]["values"]["peak_pressure"] == pytest.approx(0.6, rel=1e-9)
    assert summary["min_tawss"] == pytest.approx(exact, rel=1e-9)  # the last heartbeat's


def test_fsi_report_prints_the_heartbeats(runs):
    text = report.markdown(
        [report_runs.load_run(runs["steady"]), report_runs.load_run(runs["bdf2"])]
    )
    assert "## Heartbeats" in text
    section = text.split("## Heartbeats")[1]
    lines = [line for line in section.splitlines() if line.startswith("| ")]
    assert lines[0].startswith("| heartbeat | t (s) | steps | peak velocity (cm/s) |")
    assert lines[0].endswith("| largest change |")
    assert lines[1].startswith("| 1 | 0–0.004 | 4 |") and lines[1].endswith("| – |")
    assert lines[2].startswith("| 2 | 0.004–0.008 | 4 |")
    assert lines[2].endswith(" % |")  # the largest change from heartbeat 1


def test_mean_inlet_pressure_is_the_prescribed_pressure_and_the_outlet_mean_is_zero(runs):
    """A pressure inlet imposes σ n = −P n; for developed flow (∂u_n/∂n = 0) p = P on the inlet
    and p = 0 on the traction-free outlet: the boundary means, to the solver's tolerance."""
    _, rows = read_csv(runs["steady"] / "metrics.csv")
    case = config.load(CHANNEL, cycles_set(runs["path"]))
    pressure = fluid_boundaries.inlet_pressure(case.fluid.inlet)
    prescribed = np.array([pressure(t) for t in column(rows, "t")])
    assert column(rows, "mean_inlet_pressure") == pytest.approx(prescribed, rel=1e-9)
    assert np.abs(column(rows, "mean_outlet_pressure")).max() < 1e-9 * prescribed.max()


def test_a_restart_in_heartbeat_two_gives_the_uninterrupted_run(runs):
    """Stopped after step 6 (heartbeat 1 finished, 2 half done): its wall_indices.csv has
    heartbeat 1 complete and 2 so far; restarted, metrics.csv and wall_indices.csv equal the
    uninterrupted run's (bit for bit on one rank, round-off on two) and summary.json's
    heartbeats too."""
    assert runs["stopped_at"] == 6
    straight = read_csv(runs["bdf2"] / "wall_indices.csv")[1]
    split = read_csv(runs["split"] / "wall_indices.csv")[1]
    stopped = runs["stopped_indices"]
    assert sorted({r["cycle"] for r in stopped}) == [1, 2]
    first = [r for r in straight if r["cycle"] == 1]
    assert column([r for r in stopped if r["cycle"] == 1], "TAWSS") == pytest.approx(
        column(first, "TAWSS"), rel=1e-9
    )
    # From rest the flow is not yet periodic: the heartbeats differ.
    second = [r for r in straight if r["cycle"] == 2]
    assert not np.allclose(column(first, "TAWSS"), column(second, "TAWSS"), rtol=1e-3)
    for a, b in (
        (split, straight),
        (read_csv(runs["split"] / "metrics.csv")[1], read_csv(runs["bdf2"] / "metrics.csv")[1]),
    ):
        assert len(a) == len(b)
        for key in a[0]:
            if key == "wall_time_s":
                continue
            if isinstance(a[0][key], str):
                assert [r[key] for r in a] == [r[key] for r in b], key
            elif SERIAL:  # bit for bit (NaN: an empty cell in both)
                np.testing.assert_array_equal(column(a, key), column(b, key), err_msg=key)
            else:
                assert column(a, key) == pytest.approx(
                    column(b, key), rel=1e-7, abs=1e-12, nan_ok=True
                ), key
    beats = [
        json.loads((runs[name] / "summary.json").read_text())["cycles"]
        for name in ("split", "bdf2")
    ]
    assert [b["values"]["min_tawss"] for b in beats[0]] == pytest.approx(
        [b["values"]["min_tawss"] for b in beats[1]], rel=1e-9
    )


def test_a_step_across_a_heartbeat_counts_its_parts_for_each(shared_tmp):
    """Without time.cycles (the inlet still repeats, every 4 ms) steps of 1.5 ms: the step
    (3, 4.5] ms has its end value count 1 ms for heartbeat 1 and 0.5 ms for heartbeat 2, so
    heartbeat 1's TAWSS = (1.5 τ₁ + 1.5 τ₂ + 1 τ₃) / 4 and heartbeat 2's = (0.5 τ₃ + 1.5 τ₄) / 2
    (τ_n = P(t_n) H / 2L, steady Poiseuille); the cycle column is 1, 1, 2, 2."""
    if MPI.COMM_WORLD.rank == 0:
        (shared_tmp / "pulse.csv").write_text(pulse_csv())
    MPI.COMM_WORLD.barrier()
    overrides = [
        pulse_inlet(shared_tmp),
        "time.end=0.006",
        "time.schedule=[{until: 0.006, dt: 0.0015}]",
        "fluid.outlet.backflow_stabilization=0",
        "time.scheme=steady",
    ]
    assert fsi_run(shared_tmp / "run", overrides) == 0
    _, rows = read_csv(shared_tmp / "run" / "metrics.csv")
    assert column(rows, "cycle").tolist() == [1, 1, 2, 2]
    pressure = fluid_boundaries.inlet_pressure(config.load(CHANNEL, overrides).fluid.inlet)
    tau = [pressure(0.0015 * n) * H / (2 * L) for n in range(1, 5)]
    _, indices = read_csv(shared_tmp / "run" / "wall_indices.csv")
    for k, exact in (
        (1, (1.5 * tau[0] + 1.5 * tau[1] + tau[2]) / 4),
        (2, (0.5 * tau[2] + 1.5 * tau[3]) / 2),
    ):
        beat = [r for r in indices if r["cycle"] == k]
        assert column(beat, "TAWSS") == pytest.approx(exact, rel=1e-9)


CYCLE_ERRORS = [
    (
        ["time.cycles=2"],
        "--set: time.cycles: 2 heartbeats need a periodic inlet (a pressure_table, "
        "pressure_file, flow_rate, flow_rate_table or flow_rate_file fluid.inlet with "
        "period > 0); this inlet does not repeat: use time.end instead",
    ),
    (
        ["PULSE", "time.cycles=3", "time.end=0.005", "time.schedule=[{until: 0.004, dt: 0.001}]"],
        "--set: time.end: expected fluid.inlet.period = 0.004 s (one heartbeat) or time.cycles × "
        "period = 0.012 s (the whole run) when time.cycles is 3, got 0.005",
    ),
    (
        ["PULSE", "time.cycles=2", "time.end=0.004", "time.schedule=[{until: 0.003, dt: 0.001}]"],
        "--set: time.schedule[0].until: expected at least fluid.inlet.period = 0.004 s (with "
        "time.cycles the schedule is one heartbeat's), got 0.003",
    ),
    (
        ["PULSE", "time.cycles=-1"],
        "--set: time.cycles: expected an integer in [0, 1000] (0: time.end sets the end), got -1",
    ),
    (["PULSE", "time.cycles=1.5"], "--set: time.cycles: expected an integer, got 1.5"),
    (
        [
            "PULSE",
            "time.cycles=1000",
            "time.end=0.004",
            "time.schedule=[{until: 0.004, dt: 1.0e-6}]",
        ],
        "--set: time.schedule: 4,000,000 steps to the end of time.cycles = 1000 heartbeats, 4 s, "
        "more than time.max_steps = 1,000,000",
    ),
]


@pytest.mark.parametrize("overrides, message", CYCLE_ERRORS)
def test_bad_cycles_exit_2_naming_the_key(overrides, message, shared_tmp, capsys):
    if MPI.COMM_WORLD.rank == 0:
        (shared_tmp / "pulse.csv").write_text(pulse_csv())
    MPI.COMM_WORLD.barrier()
    overrides = [pulse_inlet(shared_tmp) if s == "PULSE" else s for s in overrides]
    code = cli.main(["check", CHANNEL, *sum((["--set", s] for s in overrides), [])])
    err = capsys.readouterr().err
    assert code == 2
    if MPI.COMM_WORLD.rank == 0:
        assert message in err and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1


def test_a_short_try_of_a_heartbeat_case_is_told_how(capsys):
    """``fsi run configs/carotid_heartbeat.yaml --set time.end=0.01``, a newcomer's first try,
    was refused without saying that ``--set time.cycles=0`` makes it possible: the message
    says so, and with it the case is valid."""
    case = "configs/carotid_heartbeat.yaml"
    capsys.readouterr()
    assert cli.main(["check", case, "--set", "time.end=0.01"]) == 2
    if MPI.COMM_WORLD.rank == 0:
        err = capsys.readouterr().err
        assert "time.end: expected fluid.inlet.period = 0.917 s (one heartbeat) or " in err
        assert (
            "when time.cycles is 3, got 0.01; to end at time.end instead (a short try), set "
            "time.cycles to 0 as well (--set time.cycles=0)\n"
        ) in err, err
    assert cli.main(["check", case, "--set", "time.end=0.01", "--set", "time.cycles=0"]) == 0


def test_one_cycle_without_a_period_is_the_plain_run():
    case = config.load(CHANNEL, ["time.cycles=1"])
    assert config.run_time(case) is case.time


# --------------------------------------------------------------------------------------------
# The location of the cap's largest principal stress


def cap_location(comm: MPI.Comm) -> tuple[dict, config.Case, list[str]]:
    """One structure step of the coarse stenosis under the inlet pressure on ``comm``: the
    metrics row, the case and the metrics columns."""
    case = config.load(
        "configs/stenosis_moving_newtonian.yaml",
        [
            "structure.interface_load=inlet_pressure",
            "time.end=0.001",
            "time.schedule=[{until: 0.001, dt: 0.001}]",
        ],
    )
    stepper = steppers.StructureStepper(case, comm)
    return stepper.step(next(iter(steps(case.time)))), case, stepper.columns


def cap_vertices(case: config.Case, comm: MPI.Comm) -> np.ndarray:
    """The reference coordinates of every vertex of a cap cell, gathered from every rank."""
    tagged = mesh.build(case, comm)
    cells = tagged.cells(Region.CAP)
    tdim = tagged.mesh.topology.dim
    nodes = compat.entities_to_geometry(tagged.mesh, tdim, cells).reshape(len(cells), -1)
    points = tagged.mesh.geometry.x[nodes.ravel()][:, :2]
    return np.concatenate(comm.allgather(points))


def test_the_cap_stress_location_is_in_the_cap_and_independent_of_the_ranks():
    """``max_principal_cap_x``/``_y`` is a vertex of a cap cell (reference coordinates), the
    largest principal stress at that node is ``max_principal_cap``, and the location found on
    all ranks is the one found by each rank alone (serially)."""
    world = MPI.COMM_WORLD
    row, case, columns = cap_location(world)
    assert columns[-2:] == ["max_principal_cap_x", "max_principal_cap_y"]
    x, y = row["max_principal_cap_x"], row["max_principal_cap_y"]
    assert math.isfinite(x) and math.isfinite(y) and row["max_principal_cap"] > 0
    distance = np.linalg.norm(cap_vertices(case, world) - np.array([x, y]), axis=1).min()
    assert distance < 1e-12
    alone, _, _ = cap_location(MPI.COMM_SELF)
    assert (alone["max_principal_cap_x"], alone["max_principal_cap_y"]) == pytest.approx(
        (x, y), abs=1e-12
    )
    assert alone["max_principal_cap"] == pytest.approx(row["max_principal_cap"], rel=1e-8)


def test_each_heartbeat_says_where_and_when_its_cap_stress_peaked():
    """summary.json's ``cycles``: the heartbeat's largest ``max_principal_cap`` with the ``t``
    and the point of that step's metrics row (the first step of equal values); a 3D row's
    ``z`` too; none where the rows have no cap stress."""
    rows = [
        {
            "t": 0.5,
            "max_principal_cap": 1.0,
            "max_principal_cap_x": 1.0,
            "max_principal_cap_y": 2.0,
        },
        {
            "t": 1.0,
            "max_principal_cap": 3.0,
            "max_principal_cap_x": 4.0,
            "max_principal_cap_y": 5.0,
        },
        {
            "t": 1.5,
            "max_principal_cap": 7.0,
            "max_principal_cap_x": 6.0,
            "max_principal_cap_y": 7.0,
            "max_principal_cap_z": 8.0,
        },
        {
            "t": 2.0,
            "max_principal_cap": 7.0,
            "max_principal_cap_x": 9.0,
            "max_principal_cap_y": 9.0,
            "max_principal_cap_z": 9.0,
        },
        {"t": 2.5, "peak_velocity": 1.0},
    ]
    beats = outputs.cycle_table(rows, 1.0, [])
    assert [b["values"].get("max_principal_cap") for b in beats] == [3.0, 7.0, None]
    assert beats[0]["where"]["max_principal_cap"] == {"t": 1.0, "x": 4.0, "y": 5.0}
    assert beats[1]["where"]["max_principal_cap"] == {"t": 1.5, "x": 6.0, "y": 7.0, "z": 8.0}
    assert beats[2]["where"] == {}
