"""The ``pressure_file`` inlet: a pressure waveform read from a CSV file, optionally periodic."""

import dataclasses
import math
import time

from mpi4py import MPI

import numpy as np
import pytest

from fsi import cli, config
from fsi.config import reader
from fsi.output import metrics_csv
from fsi.physics import fluid_boundaries

CHANNEL = "configs/channel_poiseuille.yaml"
THREE_STEPS = ["time.end=0.003", "time.schedule=[{until: 0.003, dt: 0.001}]"]
ROWS = ((0.0, 0.0), (0.0007, 35.5), (0.0011, 120.25), (0.002, 80.0), (0.0031, 150.0))


def write(path, text):
    """``text`` into ``path`` by rank 0, seen by every rank after the barrier."""
    if MPI.COMM_WORLD.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    MPI.COMM_WORLD.barrier()


def csv(rows, header="t,P\n"):
    return header + "".join(f"{t!r},{p!r}\n" for t, p in rows)


def table(rows) -> str:
    return "[" + ", ".join(f"[{t!r}, {p!r}]" for t, p in rows) + "]"


def case_file(folder, inlet, name="case.yaml"):
    """A case file in ``folder`` whose ``fluid.inlet`` is the YAML flow mapping ``inlet``."""
    path = folder / name
    write(path, f"fluid:\n  inlet: {inlet}\n")
    return path


def test_csv_inlet_equals_the_table_inlet_with_the_same_rows(shared_tmp):
    write(shared_tmp / "waves" / "w.csv", "# a comment\n" + csv(ROWS) + "\n# the end\n")
    from_file = config.load(case_file(shared_tmp, "{kind: pressure_file, file: waves/w.csv}"))
    inline = config.load(
        case_file(shared_tmp, f"{{kind: pressure_table, table: {table(ROWS)}}}", "inline.yaml")
    )
    assert from_file.fluid.inlet.table == ROWS
    assert from_file.fluid.inlet.file == str(shared_tmp / "waves" / "w.csv")
    p_file = fluid_boundaries.inlet_pressure(from_file.fluid.inlet)
    p_table = fluid_boundaries.inlet_pressure(inline.fluid.inlet)
    times = np.linspace(-0.001, 0.005, 601)
    assert [p_file(t) for t in times] == [p_table(t) for t in times]
    assert p_file(-1.0) == 0.0 and p_file(1.0) == 150.0  # held beyond the ends
    assert p_file(0.00155) == pytest.approx((120.25 + 80.0) / 2)


def test_the_period_repeats_the_waveform(shared_tmp):
    rows = ((-0.1, 7.0), (0.0, 10.0), (0.3, 90.0), (0.5, 40.0), (0.8, 10.0), (0.9, 99.0))
    write(shared_tmp / "beat.csv", csv(rows, header=""))
    case = config.load(case_file(shared_tmp, "{kind: pressure_file, file: beat.csv, period: 0.8}"))
    pressure = fluid_boundaries.inlet_pressure(case.fluid.inlet)
    for t in np.linspace(0.0, 0.8, 81):
        for k in range(1, 6):
            assert pressure(t + k * 0.8) == pytest.approx(pressure(t), rel=1e-9, abs=1e-9)
    assert pressure(0.15) == pytest.approx(50.0) and pressure(0.8 + 0.15) == pytest.approx(50.0)
    assert pressure(0.85) == pytest.approx(pressure(0.05))  # rows beyond the period are unused


def test_the_shipped_pulse_waveform_is_the_study_pulse():
    case = config.load(
        CHANNEL, ["fluid.inlet={kind: pressure_file, file: configs/waveforms/pulse.csv}"]
    )
    sampled = fluid_boundaries.inlet_pressure(case.fluid.inlet)
    pulse = fluid_boundaries.inlet_pressure(config.InletPulse())
    # linear interpolation of (A/2)(1 − cos 2πt/T) every h: error <= (A/2)(2π/T)² h²/8 = 0.3 Pa
    times = np.linspace(0, 0.01, 1001)
    assert max(abs(sampled(t) - pulse(t)) for t in times) < 0.3
    assert sampled(0.0025) == pytest.approx(1200.0)


def test_a_run_with_the_csv_inlet_equals_one_with_the_table_inlet(shared_tmp):
    write(shared_tmp / "w.csv", csv(ROWS))
    inlets = {
        "table": f"fluid.inlet={{kind: pressure_table, table: {table(ROWS)}}}",
        "file": f"fluid.inlet={{kind: pressure_file, file: {shared_tmp / 'w.csv'}}}",
    }
    metrics = {}
    for name, inlet in inlets.items():
        out = shared_tmp / name
        overrides = sum((["--set", s] for s in [*THREE_STEPS, inlet]), [])
        assert cli.main(["run", CHANNEL, "--out", str(out), *overrides]) == 0
        metrics[name] = metrics_csv.read_metrics(out / "metrics.csv")
    assert len(metrics["file"]) == 3
    assert metrics["file"][-1]["peak_pressure"] > 0
    for a, b in zip(metrics["file"], metrics["table"]):
        for column in a:
            if column != "wall_time_s":
                assert a[column] == pytest.approx(b[column], rel=1e-12, abs=1e-14), column


def test_the_dumped_configuration_is_a_table_that_loads_again(shared_tmp):
    write(shared_tmp / "w.csv", csv(ROWS))
    steps = "time: {end: 0.003, schedule: [{until: 0.003, dt: 0.001}]}\n"  # 3 steps a period
    write(
        shared_tmp / "case.yaml",
        steps + "fluid: {inlet: {kind: pressure_file, file: w.csv, period: 0.003}}\n",
    )
    case = config.load(shared_tmp / "case.yaml")
    dumped = shared_tmp / "run" / "config.yaml"  # another folder, as a run's: no w.csv there
    if MPI.COMM_WORLD.rank == 0:
        dumped.parent.mkdir()
        config.dump(case, dumped)
    MPI.COMM_WORLD.barrier()
    again = config.load(dumped)
    assert again.fluid.inlet == config.InletPressureTable(table=ROWS, period=0.003)
    as_file = dataclasses.replace(again.fluid, inlet=case.fluid.inlet)
    assert dataclasses.replace(again, fluid=as_file) == case  # everything else unchanged
    p, q = (
        fluid_boundaries.inlet_pressure(case.fluid.inlet),
        fluid_boundaries.inlet_pressure(again.fluid.inlet),
    )
    assert all(p(t) == q(t) for t in np.linspace(-0.01, 0.01, 401))
    assert config.to_dict(again) == config.to_dict(case)  # and dumping again changes nothing


def test_the_file_is_relative_to_the_case_file_or_to_the_current_directory(shared_tmp, monkeypatch):
    write(shared_tmp / "a" / "w.csv", csv(ROWS))
    case = case_file(shared_tmp / "a", "{kind: pressure_file, file: w.csv}")
    monkeypatch.chdir(shared_tmp)  # the file is found beside the case, not here
    assert config.load(case).fluid.inlet.table == ROWS
    with pytest.raises(config.ConfigError, match="^--set: fluid.inlet.file: cannot read w.csv"):
        config.load(case, ["fluid.inlet.file=w.csv"])  # --set: relative to the current directory
    assert config.load(case, ["fluid.inlet.file=a/w.csv"]).fluid.inlet.table == ROWS


BAD = [  # (CSV text or None for no file, inlet keys after the file, message after "case.yaml: ")
    (None, "", "fluid.inlet.file: cannot read {dir}/x.csv (No such file or directory)"),
    (
        "t,P\n0,0\n0.1,1\n0.2,abc\n",
        "",
        "fluid.inlet.file: {dir}/x.csv: line 4: 'abc' is not a number",
    ),
    ("0,0\n0.1,x\n", "", "fluid.inlet.file: {dir}/x.csv: line 2: 'x' is not a number"),
    ("0,0\n0.1,1_000\n", "", "fluid.inlet.file: {dir}/x.csv: line 2: '1_000' is not a number"),
    ("0,0\n0x1,1\n", "", "fluid.inlet.file: {dir}/x.csv: line 2: '0x1' is not a number"),
    (
        "0,0\n# ok\n0.2,1\n0.1,2\n",
        "",
        "fluid.inlet.file: {dir}/x.csv: line 4: t = 0.1 is not after the previous row's t = 0.2",
    ),
    (
        "0,0\n0,1\n",
        "",
        "fluid.inlet.file: {dir}/x.csv: line 2: t = 0 is not after the previous row's t = 0",
    ),
    ("t,P\n0,5\n", "", "fluid.inlet.file: {dir}/x.csv: 1 row of t, P; at least 2 are needed"),
    ("", "", "fluid.inlet.file: {dir}/x.csv: 0 rows of t, P; at least 2 are needed"),
    ("0,0\n0.1,nan\n", "", "fluid.inlet.file: {dir}/x.csv: line 2: P = nan is not a finite number"),
    ("0,0\ninf,1\n", "", "fluid.inlet.file: {dir}/x.csv: line 2: t = inf is not a finite number"),
    ("0,0\n0.1,1,2\n", "", "fluid.inlet.file: {dir}/x.csv: line 2: expected 2 columns t, P, got 3"),
    (
        "0,0\n0.5,1\n",
        ", period: 0.8",
        "fluid.inlet.period: the rows of {dir}/x.csv cover t in "
        "[0, 0.5] s, not the whole period [0, 0.8] s (the first t must be <= 0 and the last >= "
        "period)",
    ),
    (
        "0,0\n0.5,1\n",
        ", period: -1",
        "fluid.inlet.period: expected a number >= 0 (s; 0: no repetition), got -1",
    ),
    ("0,0\n0.5,1\n", ", table: [[0, 1]]", "fluid.inlet.table: not a key of kind 'pressure_file'"),
    (
        b"0,0\n0.5,\xff\n",
        "",
        "fluid.inlet.file: {dir}/x.csv: not UTF-8 text (byte 0xff at offset 8)",
    ),
]


@pytest.mark.parametrize("text,keys,message", BAD)
def test_bad_waveform_input_exits_2_with_one_line_naming_file_and_line(
    shared_tmp, capsys, text, keys, message
):
    if text is not None and MPI.COMM_WORLD.rank == 0:
        data = text if isinstance(text, bytes) else text.encode()
        (shared_tmp / "x.csv").write_bytes(data)
    case = case_file(shared_tmp, f"{{kind: pressure_file, file: x.csv{keys}}}")
    assert cli.main(["check", str(case)]) == 2
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        expected = f"fsi: error: {case}: " + message.format(dir=shared_tmp)
        assert err.startswith(expected), err
        assert err.count("\n") == 1 and "Traceback" not in err


def test_a_missing_file_key_and_an_unloaded_inlet_are_refused():
    with pytest.raises(config.ConfigError, match="fluid.inlet.file: expected the name of a CSV"):
        config.from_dict({"fluid": {"inlet": {"kind": "pressure_file"}}}, "case.yaml")
    with pytest.raises(ValueError, match="has no rows"):
        fluid_boundaries.inlet_pressure(config.InletPressureFile(file="w.csv"))


@pytest.mark.parametrize(
    "period, last, shown",
    [(1.0000001, 1.0, "[0, 1] s, not the whole period [0, 1.0000001] s"),
     (0.8, 0.79999999999, "[0, 0.79999999999] s, not the whole period [0, 0.8] s"),
     (0.6, 0.5, "[0, 0.5] s, not the whole period [0, 0.6] s")],
)  # fmt: skip
def test_a_table_short_of_its_period_shows_them_apart(period, last, shown):
    """``period: 1.0000001`` over rows to 1 said "cover t in [0, 1] s, not the whole period
    [0, 1] s": the numbers are written with the digits that tell them apart."""
    inlet = f"{{kind: pressure_table, table: [[0, 1], [{last!r}, 2]], period: {period!r}}}"
    with pytest.raises(config.ConfigError) as error:
        config.from_dict(reader.parse_yaml(f"fluid: {{inlet: {inlet}}}"), "case.yaml")
    assert f"fluid.inlet.table cover t in {shown} (the first t" in str(error.value)


def test_a_periodic_inline_table_must_cover_its_period():
    inlet = "{kind: pressure_table, table: [[0, 1], [0.5, 2]], period: 0.6}"
    with pytest.raises(
        config.ConfigError,
        match=r"case.yaml: fluid.inlet.period: "
        r"fluid.inlet.table cover t in \[0, 0.5\] s",
    ):
        config.from_dict(reader.parse_yaml(f"fluid: {{inlet: {inlet}}}"), "case.yaml")
    periodic = config.from_dict(
        reader.parse_yaml(
            "fluid: {inlet: {kind: pressure_table, table: [[0, 1], [0.5, 2]], period: 0.5}}"
        )
    )
    pressure = fluid_boundaries.inlet_pressure(periodic.fluid.inlet)
    assert pressure(0.25) == pytest.approx(1.5) and pressure(0.75) == pytest.approx(1.5)
    assert math.isclose(pressure(1.0 + 0.1), pressure(0.1))


@pytest.mark.parametrize(
    "header, message",
    [
        ("t (ms),P (mmHg)\n", "the header gives t in 'ms'; the file is read with t in s"),
        ("t (s),P (mmHg)\n", "the header gives P in 'mmHg'; the file is read with P in Pa"),
        ("t [s],P [kPa]\n", "the header gives P in 'kPa'"),
    ],
)
def test_a_header_naming_other_units_is_refused(shared_tmp, capsys, header, message):
    """A file whose header says ms or mmHg would be read as s and Pa: refused, naming the
    line and the unit; the units it is read in, or none, are accepted."""
    path = shared_tmp / "units.csv"
    write(path, csv(ROWS, header=header))
    inlet = ["--set", f"fluid.inlet={{kind: pressure_file, file: {path}}}"]
    capsys.readouterr()
    assert cli.main(["check", CHANNEL, *inlet]) == 2
    if MPI.COMM_WORLD.rank == 0:
        assert f"{path}: line 1: {message}" in capsys.readouterr().err
    for k, fine in enumerate(("t (s),P (Pa)\n", "time,pressure\n")):
        path = shared_tmp / f"fine{k}.csv"  # a new file: another rank may still read the last
        write(path, csv(ROWS, header=fine))
        inlet = ["--set", f"fluid.inlet={{kind: pressure_file, file: {path}}}"]
        assert cli.main(["check", CHANNEL, *inlet]) == 0


def test_a_period_of_fewer_than_4_steps_is_warned_of(capsys):
    """``period: 0.002`` with 1 ms steps samples the waveform twice a period: ``fsi check``
    warns, naming the key and the step."""
    short = "fluid.inlet={kind: pressure_table, table: [[0, 0], [0.002, 1]], period: 0.002}"
    capsys.readouterr()
    assert (
        cli.main(["check", CHANNEL, "--set", short, *sum([["--set", s] for s in THREE_STEPS], [])])
        == 0
    )
    if MPI.COMM_WORLD.rank == 0:
        err = capsys.readouterr().err
        assert "fsi: warning: fluid.inlet.period = 0.002 s holds 2 of the schedule's" in err
        assert "largest steps (dt = 0.001 s)" in err
    ok = "fluid.inlet={kind: pressure_table, table: [[0, 0], [0.004, 1]], period: 0.004}"
    capsys.readouterr()
    assert (
        cli.main(["check", CHANNEL, "--set", ok, *sum([["--set", s] for s in THREE_STEPS], [])])
        == 0
    )
    assert "warning" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "header, accepted",
    [("t (s),Q (m^3/s)", True), ("t,Q [m³/s]", True), ("t,Q", True), ("t (s),Q (m^2/s)", False)],
)
def test_an_axisymmetric_flow_rate_file_is_checked_in_cubic_metres_per_second(
    shared_tmp, capsys, header, accepted
):
    """An axisymmetric case's flow rate is a pipe's, m³/s (docs/axisymmetric.md): a header
    saying so is accepted, one saying m²/s (the plane model's) refused, naming the unit the
    file is read in; the check was the wrong way round."""
    lines = open("configs/waveforms/carotid_flow_3d.csv").read().splitlines()
    rows = [r for r in lines if r and not r.startswith("#")][1:]  # without its header "t,Q"
    path = shared_tmp / f"flow_{'m3' if accepted else 'm2'}_{len(header)}.csv"
    write(path, "\n".join([header, *rows]) + "\n")
    case = "configs/axisymmetric/carotid_heartbeat.yaml"
    capsys.readouterr()
    status = cli.main(["check", case, "--set", f"fluid.inlet.file={path}"])
    err = capsys.readouterr().err
    assert status == (0 if accepted else 2), err
    if not accepted and MPI.COMM_WORLD.rank == 0:
        assert f"{path}: line 1: the header gives Q in 'm^2/s'" in err
        assert "read with Q in m^3/s (an axisymmetric case's flow rate)" in err


@pytest.mark.parametrize(
    "inlet",
    [
        "{kind: pressure_table, table: [[0, 0], [1.0e-9, 1]], period: 1.0e-9}",
        "{kind: flow_rate, formula: '1e-3*sin(2*pi*t/1e-8)', period: 1.0e-8}",
        "{kind: flow_rate, formula: '1e-3', period: 1.0e-300, profile: womersley}",
        "{kind: flow_rate, formula: '1e-3', period: 5.0e-4, profile: womersley}",
    ],
)
def test_a_period_shorter_than_a_step_is_refused(capsys, inlet):
    """A period in the wrong unit (1e-9 s, 1e-300 s) with 1 ms steps made each step close
    every heartbeat it spans (10⁶ per step; 10²⁹⁷ grew to 24 GB and had to be killed): refused
    before anything runs, naming the key, the step and how many heartbeats a step would span;
    a period of exactly one step is allowed."""
    sets = sum([["--set", s] for s in THREE_STEPS], [])
    capsys.readouterr()
    start = time.perf_counter()
    assert cli.main(["check", CHANNEL, "--set", f"fluid.inlet={inlet}", *sets]) == 2
    assert time.perf_counter() - start < 10
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert err.startswith("fsi: error: --set: fluid.inlet.period: "), err
        assert "is shorter than the schedule's largest step (dt = 0.001 s)" in err
        assert "a step would span" in err and "heartbeats" in err
    one_step = "fluid.inlet={kind: pressure_table, table: [[0, 0], [0.001, 1]], period: 0.001}"
    assert cli.main(["check", CHANNEL, "--set", one_step, *sets]) == 0
