"""``fsi report``: the study's tables and plots from run folders."""

import csv
import json
import math
import shutil
import tempfile
from dataclasses import replace
from pathlib import Path

from mpi4py import MPI

import pytest
import support_run

from fsi import cli, config
from fsi.output import metrics_csv, report, report_figures, report_runs, units

SHORT = [
    "structure.mode=rigid",
    "time.end=0.004",
    "time.schedule=[{until: 0.004, dt: 0.001}]",
    "output.report_times=[0.002, 0.004]",
]


@pytest.fixture(scope="module")
def run_dir():
    """A 4-step rigid run in a folder shared by the ranks (see conftest.shared_tmp)."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    out = path / "rigid"
    assert (
        cli.main(
            [
                "run",
                "configs/stenosis_fixed_newtonian.yaml",
                "--out",
                str(out),
                *sum((["--set", s] for s in SHORT), []),
            ]
        )
        == 0
    )
    yield out
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def test_tables_hold_the_rows_at_the_report_times(run_dir, capsys):
    run = report_runs.load_run(run_dir)
    rows = metrics_csv.read_metrics(run_dir / "metrics.csv")
    by_t = {round(r["t"], 9): r for r in rows}
    table = report.peaks_table([run], "peak_velocity", "Peak velocity", "velocity")
    unit = units.choose_unit("velocity", [by_t[t]["peak_velocity"] for t in (0.002, 0.004)])
    assert table.startswith(f"| Peak velocity ({unit.name}) | t = 0.002 s | t = 0.004 s |")
    cells = table.splitlines()[2].split("|")[2:-1]
    assert [float(c) for c in cells] == [
        pytest.approx(unit.scale * by_t[t]["peak_velocity"], rel=1e-3) for t in (0.002, 0.004)
    ]
    # A time with no step is shown as '–', not interpolated.
    assert report.value_at(rows, 0.0025, "peak_velocity") is None
    assert "| 4 | 0.004 |" in report.effort_table([run])


def test_cli_writes_report_and_plots(run_dir, capsys):
    out = run_dir.parent / f"report{MPI.COMM_WORLD.rank}"
    again = run_dir.parent / "rigid_again"  # a second run (a folder given twice is refused)
    if MPI.COMM_WORLD.rank == 0 and not again.exists():
        shutil.copytree(run_dir, again, ignore=shutil.ignore_patterns("fields*", "solid*"))
    MPI.COMM_WORLD.barrier()
    assert cli.main(["report", str(run_dir), str(again), "--out", str(out)]) == 0
    if MPI.COMM_WORLD.rank == 0:
        text = (out / "report.md").read_text()
        assert "Table 1: Peak velocity" in text and "Table 3: Peak displacement" in text
        assert text.startswith(report.markdown(report_runs.load_runs([run_dir, again])))
        assert (out / "peak_velocity.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert (out / "flow_rate.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert not (out / "max_sss.png").exists()  # a rigid run has no structure stress
        assert "Table 2: Peak pressure" in capsys.readouterr().out


def test_an_old_run_folder_without_flow_rates_still_reports(run_dir, capsys):
    """Run folders written before the flow-rate columns existed: the tables and the other
    plots as before, no flow-rate plot (and no error)."""
    comm = MPI.COMM_WORLD
    old = run_dir.parent / "old"
    if comm.rank == 0:
        shutil.copytree(run_dir, old, dirs_exist_ok=True)
        with (run_dir / "metrics.csv").open(newline="") as f:
            rows = list(csv.DictReader(f))
        columns = [c for c in rows[0] if c not in ("inlet_flow_rate", "outlet_flow_rate")]
        with (old / "metrics.csv").open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
            writer.writeheader()
            writer.writerows(rows)
    comm.barrier()
    assert "inlet_flow_rate" not in report_runs.load_run(old).rows[0]
    out = run_dir.parent / f"old_report{comm.rank}"
    assert cli.main(["report", str(old), str(run_dir), "--out", str(out)]) == 0
    assert support_run.flow_rate_plot([report_runs.load_run(old)], out / "none.png") is False
    if comm.rank == 0:
        lines = (out / "report.md").read_text().splitlines()
        old_rows = [i for i, line in enumerate(lines) if line.startswith("| old (")]
        assert len(old_rows) == 4  # Tables 1–3 and the solver effort
        for i in old_rows:  # the same numbers as the run it was copied from
            assert lines[i].replace("| old (", f"| {run_dir.name} (") == lines[i + 1]
        assert (out / "flow_rate.png").exists()  # the new run's lines
        assert not (out / "none.png").exists()


def test_a_folder_that_is_not_a_run_is_refused(shared_tmp, capsys):
    assert cli.main(["report", str(shared_tmp / "nothing")]) == 2
    if MPI.COMM_WORLD.rank == 0:
        assert "no config.yaml (not a folder written by fsi run)" in capsys.readouterr().err


@pytest.mark.parametrize(
    "times, message",
    [
        (["nan"], "--times nan: expected a finite time >= 0 (s)"),
        (["-1"], "--times -1.0: expected a finite time >= 0 (s)"),
        (["inf"], "--times inf: expected a finite time >= 0 (s)"),
        (["0.002", "0.002"], "--times 0.002: given twice"),
    ],
)
def test_report_times_that_are_not_times_are_refused(run_dir, capsys, times, message):
    """A report time that is not a finite time ≥ 0, or one given twice, is refused (exit 2,
    one line naming --times) before any table is printed, as ``fsi plot --time`` is."""
    assert cli.main(["report", str(run_dir), "--times", *times]) == 2
    if MPI.COMM_WORLD.rank == 0:
        captured = capsys.readouterr()
        assert captured.err == f"fsi: error: {message}\n"
        assert captured.out == ""


# --------------------------------------------------------------------------------------------
# Damaged run folders: a row cut short at the end is left out, anything else is refused


def copy_with_metrics(run_dir: Path, copy: Path, change) -> Path:
    """``copy``, a copy of the run folder whose metrics.csv lines (bytes with their line ends,
    the header first) are replaced by ``change(lines)``."""
    if MPI.COMM_WORLD.rank == 0:
        shutil.copytree(run_dir, copy)
        lines = (run_dir / "metrics.csv").read_bytes().splitlines(keepends=True)
        (copy / "metrics.csv").write_bytes(b"".join(change(lines)))
    MPI.COMM_WORLD.barrier()
    return copy


def set_cell(line: int, column: str, value: bytes):
    """A change of metrics.csv: the cell of ``column`` in line ``line`` (1: the header)."""

    def change(lines: list[bytes]) -> list[bytes]:
        header = lines[0].decode().rstrip("\r\n").split(",")
        cells = lines[line - 1].rstrip(b"\r\n").split(b",")
        cells[header.index(column)] = value
        return lines[: line - 1] + [b",".join(cells) + b"\r\n"] + lines[line:]

    return change


def test_a_row_cut_short_at_the_end_is_left_out(run_dir, shared_tmp, capsys, fsi_log):
    """A run killed (or still running) while writing its last row: the complete rows are
    reported, the cut one is left out with a warning naming the line."""
    comm = MPI.COMM_WORLD
    cut = copy_with_metrics(run_dir, shared_tmp / "cut", lambda lines: lines[:4] + [lines[4][:25]])
    assert [r["step"] for r in report_runs.load_run(cut).rows] == [1, 2, 3]
    assert cli.main(["report", str(cut), "--times", "0.002", "0.004"]) == 0
    if comm.rank == 0:
        out = capsys.readouterr().out
        row = next(
            line for line in out.splitlines() if line.startswith("| cut (") and "| 3 |" in line
        )  # the solver effort: 3 steps
        assert "| 0.003 |" in row
        assert f"{cut / 'metrics.csv'}: line 5 is cut short" in fsi_log.text


@pytest.mark.parametrize(
    "change, expected",
    [
        (
            set_cell(3, "peak_velocity", b"1.2.3"),
            "line 3: peak_velocity: '1.2.3' is not a finite number",
        ),
        (
            set_cell(4, "peak_pressure", b"nan"),
            "line 4: peak_pressure: 'nan' is not a finite number",
        ),
        (set_cell(3, "step", b"2.5"), "line 3: step: '2.5' is not a step number (1, 2, ...)"),
        (set_cell(3, "t", b""), "line 3: t: empty"),
        (set_cell(2, "dt", b"0.001,7"), "line 2: "),  # one cell too many
        (set_cell(4, "max_wss", b"\xff\xfe"), "line 4: not UTF-8 text"),
        (lambda lines: lines[:2] + [lines[2][:12] + b"\r\n"] + lines[3:], "line 3: "),
        (
            lambda lines: [lines[0].replace(b"step,", b"steps,")] + lines[1:],
            "line 1: no 'step' column (not a metrics table)",
        ),
    ],
)
def test_a_damaged_metrics_table_is_refused(run_dir, shared_tmp, capsys, change, expected):
    """Exit 2 with one line naming the file and the line, no traceback."""
    damaged = copy_with_metrics(run_dir, shared_tmp / "damaged", change)
    assert cli.main(["report", str(damaged)]) == 2
    if MPI.COMM_WORLD.rank == 0:
        err = capsys.readouterr().err
        assert err.startswith(f"fsi: error: {damaged / 'metrics.csv'}: {expected}")
        assert len(err.splitlines()) == 1


def test_a_damaged_summary_is_refused(run_dir, shared_tmp, capsys):
    damaged = copy_with_metrics(run_dir, shared_tmp / "damaged", lambda lines: lines)
    if MPI.COMM_WORLD.rank == 0:
        (damaged / "summary.json").write_text('{"steps": 4, "wall')
    MPI.COMM_WORLD.barrier()
    assert cli.main(["report", str(damaged)]) == 2
    if MPI.COMM_WORLD.rank == 0:
        assert f"fsi: error: {damaged / 'summary.json'}: unreadable" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------
# Units and scales


@pytest.mark.parametrize(
    "quantity, values, unit, shown",
    [
        ("stress", [300.0, -12.0], "Pa", 300.0),
        ("stress", [300.0, 17.0e3], "kPa", 17.0),
        ("stress", [-2.5e3, 10.0], "kPa", 2.5),  # the magnitude decides
        ("stress", [2.0e6], "MPa", 2.0),
        ("stress", [0.5], "Pa", 0.5),  # below 1 in every unit: the smallest
        ("stress", [], "Pa", None),
        ("pressure", [1200.0], "kPa", 1.2),
        ("displacement", [3.0e-4], "µm", 300.0),
        ("displacement", [5.0e-6, 1.5e-3], "mm", 1.5),
        ("displacement", [1.0e-9], "µm", 1.0e-3),
        ("velocity", [0.3], "cm/s", 30.0),
        ("velocity", [1.2], "m/s", 1.2),
        ("length", [0.004], "mm", 4.0),
        ("flow_rate", [2.0e-5], "cm²/s", 0.2),
        ("count", [7.0], "", 7.0),
    ],
)
def test_the_unit_is_the_largest_one_the_largest_value_is_at_least_1_in(
    quantity, values, unit, shown
):
    chosen = units.choose_unit(quantity, values)
    assert chosen.name == unit
    if shown is not None:
        assert chosen.scale * max(values, key=abs) == pytest.approx(
            math.copysign(shown, max(values, key=abs))
        )


@pytest.mark.parametrize(
    "series, scale",
    [
        ([[300.0, 280.0]], "linear"),  # one run
        ([[300.0, 150.0], [1700.0, 900.0]], "linear"),  # within 10×
        ([[1.0], [10.0]], "linear"),  # exactly 10×
        ([[1.0], [10.01]], "log"),
        ([[300.0, 150.0], [17.0e3, 9.0e3]], "log"),  # fixed vs moving wall SSS
        ([[300.0, 150.0], [17.0e3, -9.0e3]], "panels"),  # a value ≤ 0: no log axis
        ([[0.0, 0.0], [0.004, 0.002]], "panels"),  # no recirculation beside 4 mm of it
        ([[-0.5, 0.2], [-0.4, 0.1]], "linear"),
        ([[0.0], [0.0]], "linear"),
        ([[], [17.0e3]], "linear"),  # a run without the column does not count
        ([], "linear"),
    ],
)
def test_the_scale_is_linear_log_or_panels_from_the_magnitudes(series, scale):
    assert report_runs.choose_scale(series) == scale


# --------------------------------------------------------------------------------------------
# Synthetic run folders: a fixed wall (~300 Pa) and a moving wall (~17 kPa)

PULSE = 0.005  # s
STEPS, DT = 40, 2.5e-4  # to 10 ms


def pulse(t: float) -> float:
    """0 → 1 (at 2.5 ms) → 0 over the 5 ms pulse, 0 after."""
    return math.sin(math.pi * t / PULSE) ** 2 if t <= PULSE else 0.0


def study_columns(stress: float, displacement: float, recirculation: float) -> dict:
    """metrics.csv columns (functions of t) of a coupled stenosis run whose stresses peak at
    about ``stress`` (Pa) and displacement at ``displacement`` (m)."""
    return {
        "peak_velocity": lambda t: 0.3 * (0.02 + pulse(t)),
        "peak_pressure": lambda t: 1200.0 * (0.01 + pulse(t)),
        "peak_displacement": lambda t: displacement * (0.01 + pulse(t)),
        "max_sss": lambda t: stress * (0.05 + pulse(t)),
        "coupling_iterations": lambda t: 3.0 + round(2 * pulse(t)),
        "wall_time_s": lambda t: 0.3,
        "min_wss": lambda t: -0.1 * stress / 300.0 * pulse(t),
        "max_wss": lambda t: stress / 300.0 * (0.01 + pulse(t)),
        "recirculation_length": lambda t: recirculation * pulse(t),
        "inlet_flow_rate": lambda t: 2.0e-5 * pulse(t),
        "outlet_flow_rate": lambda t: 1.8e-5 * pulse(t),
        "mean_inlet_pressure": lambda t: 1200.0 * pulse(t),
        "mean_outlet_pressure": lambda t: 40.0 * pulse(t),
        "max_von_mises": lambda t: 1.7 * stress * (0.05 + pulse(t)),
        "max_principal": lambda t: 1.2 * stress * (0.05 + pulse(t)),
        **{
            f"max_{name}_{region}": (lambda t, f=f: f * stress * (0.05 + pulse(t)))
            for name in ("sss", "von_mises", "principal")
            for region, f in (("wall", 0.4), ("lipid", 0.3), ("cap", 0.9))
        },
        # the cap's and the lipid's SSS cross: the plaque's maximum is each in turn
        "max_sss_cap": lambda t: stress * pulse(t),
        "max_sss_lipid": lambda t: 0.5 * stress * (1.0 - pulse(t)),
    }


def synthetic_run(folder: Path, case: config.Case, columns: dict, finished: bool = True) -> Path:
    """A run folder written by hand: config.yaml, metrics.csv (``STEPS`` steps of ``DT``;
    ``columns`` maps a column to its value as a function of t) and, for a finished run,
    summary.json."""
    folder.mkdir(parents=True)
    config.dump(case, folder / "config.yaml")
    with (folder / "metrics.csv").open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["step", "t", "dt", *columns])
        for step in range(1, STEPS + 1):
            t = step * DT
            writer.writerow(
                [step, repr(t), repr(DT), *(repr(value(t)) for value in columns.values())]
            )
    if finished:
        (folder / "summary.json").write_text(json.dumps({"steps": STEPS}))
    return folder


def stenosis_case(mode: str, **inlet) -> config.Case:
    case = config.Case(name=mode, structure=replace(config.Structure(), mode=mode))
    if inlet:
        case = replace(case, fluid=replace(case.fluid, inlet=config.InletPressure(**inlet)))
    return case


@pytest.fixture
def folder(shared_tmp) -> Path:
    """A folder of this rank's own (the report is made on each rank here)."""
    return shared_tmp / f"rank{MPI.COMM_WORLD.rank}"


@pytest.fixture
def fixed_and_moving(folder) -> list[Path]:
    return [
        synthetic_run(
            folder / "fixed", stenosis_case("fixed_wall"), study_columns(300.0, 5.0e-6, 0.0)
        ),
        synthetic_run(
            folder / "moving", stenosis_case("moving_wall"), study_columns(17.0e3, 2.3e-4, 0.004)
        ),
    ]


def captions(report_md: str) -> dict[str, str]:
    """PNG name → its caption line in report.md (the line after the picture)."""
    lines = report_md.splitlines()
    found = {}
    for line, after in zip(lines, lines[1:]):
        if line.startswith("![") and line.endswith(".png)"):
            name = line[line.index("](") + 2 : -1]
            assert line == f"![{name}]({name})" and after.startswith(f"*{name}*: ")
            found[name] = after
    return found


def test_every_plot_is_written_for_a_fixed_and_a_moving_wall(fixed_and_moving, folder):
    runs = [report_runs.load_run(path) for path in fixed_and_moving]
    written = report.write(runs, folder / "report")
    names = [path.name for path in written]
    assert names == ["report.md"] + [f"{figure.name}.png" for figure in report_figures.FIGURES]
    assert {
        "max_sss.png",
        "max_sss_plaque.png",
        "max_principal_cap.png",
        "peak_pressure.png",
        "wall_shear_stress.png",
        "inlet_pressure.png",
        "flow_rate.png",
        "boundary_pressure.png",
    } <= set(names)
    for path in written[1:]:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = written[0].read_text()
    found = captions(text)
    assert list(found) == names[1:]  # every PNG, in order, with a caption line
    # 300 Pa beside 17 kPa, all positive: a log axis; signed WSS and no recirculation beside
    # 4 mm of it: one panel per run; velocities alike: linear.
    for name in (
        "max_sss.png",
        "max_sss_plaque.png",
        "max_principal_cap.png",
        "peak_displacement.png",
    ):
        assert "Log y-axis: the runs' magnitudes differ by more than 10×." in found[name]
    for name in ("wall_shear_stress.png", "recirculation_length.png"):
        assert "One panel per run (each its own y-range)" in found[name]
    for name in (
        "peak_velocity.png",
        "peak_pressure.png",
        "coupling_iterations.png",
        "flow_rate.png",
        "inlet_pressure.png",
    ):
        assert "Log y-axis" not in found[name] and "One panel" not in found[name]
    # The tables in readable units: µm, kPa, cm/s, with 4 significant digits.
    markdown = report.markdown(runs, [0.0025, 0.005])
    assert "| Peak displacement (µm) | t = 0.0025 s | t = 0.005 s |" in markdown
    assert "| moving (moving_wall, newtonian, coarse) | 232.3 | 2.3 |" in markdown
    assert "| fixed (fixed_wall, newtonian, coarse) | 5.05 | 0.05 |" in markdown
    assert "| Peak pressure (kPa) | t = 0.0025 s | t = 0.005 s |" in markdown
    assert "| Peak velocity (cm/s) | t = 0.0025 s | t = 0.005 s |" in markdown


def test_the_plaque_curve_is_the_larger_of_the_cap_and_the_lipid(fixed_and_moving):
    run = report_runs.load_run(fixed_and_moving[1])
    plaque = report_figures.FIGURES[
        [f.name for f in report_figures.FIGURES].index("max_sss_plaque")
    ]
    (group,) = plaque.groups([run])
    (line,) = group.lines
    assert line.t == [r["t"] for r in run.rows]
    assert line.y == [max(r["max_sss_cap"], r["max_sss_lipid"]) for r in run.rows]
    assert {r["max_sss_cap"] > r["max_sss_lipid"] for r in run.rows} == {True, False}


def test_the_inlet_waveform_is_plotted_for_pressure_inlets_only(folder):
    columns = {"peak_velocity": lambda t: 0.2}
    pulse_a = synthetic_run(folder / "a", stenosis_case("rigid"), columns)
    pulse_b = synthetic_run(folder / "b", stenosis_case("rigid"), columns, finished=False)
    formula = synthetic_run(
        folder / "c", stenosis_case("rigid", formula="800*sin(pi*t/0.01)**2"), columns
    )
    velocity = synthetic_run(folder / "d", config.load("configs/turek_hron_cfd1.yaml"), columns)
    runs = [report_runs.load_run(path) for path in (pulse_a, velocity, pulse_b, formula)]
    groups = report_figures.inlet_pressure_groups(runs)
    assert [g.label.split(":")[0] for g in groups] == ["a, b", "c"]  # one line per waveform
    (shared,), (own,) = (g.lines for g in groups)
    assert shared.t[0] == 0 and shared.t[-1] == pytest.approx(STEPS * DT)
    assert max(shared.y) == pytest.approx(1200.0)  # the study's pulse, at t = 2.5 ms
    assert all(p == 0 for t, p in zip(shared.t, shared.y) if t > PULSE)
    assert own.y == [pytest.approx(800 * math.sin(math.pi * t / 0.01) ** 2) for t in own.t]
    assert "inlet_pressure.png" in [p.name for p in report.write(runs, folder / "with")]
    # A velocity inlet has no P(t): no plot.
    assert report_figures.inlet_pressure_groups(runs[1:2]) == []
    written = report.write(runs[1:2], folder / "without")
    assert "inlet_pressure.png" not in [p.name for p in written]
    assert not (folder / "without" / "inlet_pressure.png").exists()


def test_old_runs_without_the_new_columns_still_report(fixed_and_moving, folder, capsys):
    """A stopped run written before peak_pressure, the WSS, the flow rates and the per-region
    stresses existed: '–' in Table 2, left out of those plots, which are not written when no
    run has them."""
    old_columns = {
        k: v
        for k, v in study_columns(300.0, 5.0e-6, 0.0).items()
        if k
        in ("peak_velocity", "peak_displacement", "max_sss", "coupling_iterations", "wall_time_s")
    }
    old = synthetic_run(folder / "old", stenosis_case("fixed_wall"), old_columns, finished=False)
    written = {p.name for p in report.write([report_runs.load_run(old)], folder / "alone")}
    assert written == {
        "report.md",
        "max_sss.png",
        "peak_velocity.png",
        "peak_displacement.png",
        "coupling_iterations.png",
        "inlet_pressure.png",
    }
    text = (folder / "alone" / "report.md").read_text()
    assert "| old (fixed_wall, newtonian, coarse) | – | – | – | – | – |" in text  # Table 2
    assert "| old (fixed_wall, newtonian, coarse) | 40 (stopped) | 0.01 |" in text
    assert set(captions(text)) == written - {"report.md"}
    # Beside a new run: every plot, the old run's lines where it has the column.
    runs = [report_runs.load_run(old), report_runs.load_run(fixed_and_moving[1])]
    assert len(report.write(runs, folder / "beside")) == 1 + len(report_figures.FIGURES)
    assert [len(g.lines[0].t) for g in report_figures.maximum_groups(runs, ("max_sss_cap",))] == [
        0,
        40,
    ]
    # The command line, in-process (the report is made on rank 0).
    out = folder.parent / "cli"
    assert cli.main(["report", str(old), str(fixed_and_moving[1]), "--out", str(out)]) == 0
    if MPI.COMM_WORLD.rank == 0:
        assert len(captions((out / "report.md").read_text())) == len(report_figures.FIGURES)
        assert "| Peak displacement (µm) |" in capsys.readouterr().out


def test_the_boundary_pressures_are_the_mean_inlet_and_outlet_pressures(fixed_and_moving):
    run = report_runs.load_run(fixed_and_moving[0])
    (group,) = report_figures.boundary_pressure_groups([run])
    inlet, outlet = group.lines
    assert (inlet.style, outlet.style) == ("-", "--")
    assert inlet.t == outlet.t == [r["t"] for r in run.rows]
    assert inlet.y == [r["mean_inlet_pressure"] for r in run.rows]
    assert outlet.y == [r["mean_outlet_pressure"] for r in run.rows]


def test_heartbeat_ends_are_the_multiples_of_each_period_up_to_the_end():
    assert report_figures.heartbeat_ends([0.004], 0.01) == pytest.approx([0.004, 0.008])
    assert report_figures.heartbeat_ends([0.0025], 0.01) == pytest.approx(
        [0.0025, 0.005, 0.0075, 0.01]
    )
    assert report_figures.heartbeat_ends([0.004, 0.002], 0.008) == pytest.approx(
        [0.002, 0.004, 0.006, 0.008]
    )
    assert (
        report_figures.heartbeat_ends([], 1.0) == []
        and report_figures.heartbeat_ends([0.5], 0.4) == []
    )


def test_runs_with_heartbeats_have_them_marked_and_said(folder):
    """With a periodic inlet every time plot has a dotted line at each heartbeat's end, and its
    caption says so; without one, neither."""
    beating = config.from_dict(
        {
            "name": "beats",
            "structure": {"mode": "rigid"},
            "time": {"end": STEPS * DT, "schedule": [{"until": STEPS * DT, "dt": DT}]},
            "fluid": {
                "inlet": {
                    "kind": "pressure_table",
                    "table": [[0.0, 0.0], [0.002, 100.0], [0.004, 0.0]],
                    "period": 0.004,
                }
            },
        }
    )
    columns = {"peak_velocity": lambda t: 0.2 + t, "mean_inlet_pressure": lambda t: 50.0}
    runs = [report_runs.load_run(synthetic_run(folder / "beats", beating, columns))]
    text = report.write(runs, folder / "beats_report")[0].read_text()
    note = "Dotted vertical lines: the ends of the heartbeats (period 0.004 s)."
    for name in ("peak_velocity.png", "inlet_pressure.png", "boundary_pressure.png"):
        assert note in captions(text)[name]
    plain = [report_runs.load_run(synthetic_run(folder / "plain", stenosis_case("rigid"), columns))]
    assert (
        "Dotted vertical lines" not in report.write(plain, folder / "plain_report")[0].read_text()
    )


def test_a_run_given_twice_is_refused(folder, capsys):
    """``fsi report R R`` tabled every row twice without a word: a run folder given twice, as
    the same or another spelling (``R/../R``), is refused, exit 2, naming it; nothing written."""
    run = synthetic_run(folder / "R", stenosis_case("fixed_wall"), study_columns(300, 5e-6, 0))
    out = folder / "twice"
    for second, said in ((str(run), ""), (f"{run}/../R", f" (as {run})")):
        capsys.readouterr()
        assert cli.main(["report", str(run), second, "--out", str(out)]) == 2
        if MPI.COMM_WORLD.rank == 0:
            err = capsys.readouterr().err
            assert (
                err == f"fsi: error: RUN_DIR {Path(second)}: given twice{said}: each run is "
                "tabled once\n"
            ), err
    assert not out.exists()


def test_report_times_after_a_short_run_are_said_to_be_unreached(folder, capsys):
    """``fsi report`` without ``--times`` on a run that stops before the case's report times
    printed tables of '–' without a word: a note names the times, the runs' end and
    ``--times``; with ``--times`` within the run, or report times it reaches, no note."""
    case = replace(stenosis_case("fixed_wall"), output=config.Output(
        report_times=(0.005, 0.02, 0.05)))  # fmt: skip
    run = synthetic_run(folder / "short", case, study_columns(300, 5e-6, 0))  # to 10 ms
    text = report.markdown(report_runs.load_runs([run]))
    assert text.startswith(
        "**Note**: no run reaches the report times 0.02, 0.05 s (output.report_times of short): "
        "the runs end by t = 0.01 s, and those columns hold '–'. Give times within the runs: "
        "`fsi report ... --times T ...`."
    ), text[:300]
    assert "Note" not in report.markdown(report_runs.load_runs([run]), [0.005])
    reached = replace(case, name="reached", output=config.Output(report_times=(0.005,)))
    other = synthetic_run(folder / "reached", reached, study_columns(300, 5e-6, 0))
    assert "Note" not in report.markdown(report_runs.load_runs([other]))


def test_runs_in_folders_of_the_same_name_are_told_apart(folder, capsys):
    """``fsi report A/run B/run``: each run is named with as many parent folders as it takes,
    in the tables, the legends and the pictures' file names (none written over another)."""
    assert report_runs.unique_names([Path("x/A/run"), Path("x/B/run"), Path("y/other")]) == [
        "A/run",
        "B/run",
        "other",
    ]
    assert report_runs.unique_names([Path("x/A/run"), Path("x/A/run")]) == [
        "run",
        "run",
    ]  # the same
    paths = []
    for parent, stress in (("A", 300.0), ("B", 600.0)):
        run = synthetic_run(
            folder / parent / "run", stenosis_case("fixed_wall"), study_columns(stress, 5e-6, 0.0)
        )
        (run / "wall_indices.csv").write_text(
            f"wall,side,x,y,TAWSS,OSI,RRT\ninterface,lower,0.0,0,{stress / 100},0.1,1\n"
            f"interface,lower,0.001,0,{stress / 50},0.2,1\n"
        )
        paths.append(run)
    out = folder / "same_names"
    assert cli.main(["report", *map(str, paths), "--out", str(out)]) == 0
    if MPI.COMM_WORLD.rank == 0:  # the report is rank 0's (each rank made its own folders)
        text = (out / "report.md").read_text()
        assert "| A/run (fixed_wall, newtonian, coarse) |" in text
        assert "| B/run (fixed_wall, newtonian, coarse) |" in text
        for name in ("A_run_tawss.png", "B_run_tawss.png", "A_run_osi.png", "B_run_osi.png"):
            assert (out / name).is_file() and f"![{name}]({name})" in text
        assert "A/run: time-averaged wall shear stress" in text
