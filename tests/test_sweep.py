"""``fsi sweep``: the product of the --vary values, one folder per run, the table and plots,
resuming, failures and stops recorded, and bad input refused before any run (1 and N ranks)."""

import csv
import json
import os
import signal
import threading
import time

from mpi4py import MPI

import pytest

from fsi import cli, config
from fsi.output import metrics_csv
from fsi.run import sweep, sweep_execution, sweep_results

STENOSIS = "configs/stenosis_moving_newtonian.yaml"
CHANNEL = "configs/channel_poiseuille.yaml"
TWO_STEPS = ["--set", "time.end=0.0005"]  # the stenosis's first two 0.25 ms steps


def sweep_main(case: str, out, *options: str) -> int:
    return cli.main(["sweep", case, "--out", str(out), *options])


def read_table(out) -> list[dict[str, str]]:
    with (out / "sweep.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def stamps(folder) -> dict[str, int]:
    """Modification times (ns) of every file below ``folder``."""
    return {str(p): p.stat().st_mtime_ns for p in folder.rglob("*") if p.is_file()}


def rank0_stderr(capsys) -> str:
    """Rank 0's stderr (the progress and error lines are printed there alone), on every rank."""
    return MPI.COMM_WORLD.bcast(capsys.readouterr().err, root=0)


# --------------------------------------------------------------------------------------------
# Pure parts


def test_values_split_at_commas_outside_brackets_and_quotes():
    assert sweep.split_values("0.4, 0.5") == ["0.4", "0.5"]
    assert sweep.split_values("[bottom],[bottom, top]") == ["[bottom]", "[bottom, top]"]
    assert sweep.split_values("{model: carreau, n: 0.5},'a,b'") == [
        "{model: carreau, n: 0.5}",
        "'a,b'",
    ]


def test_folder_names_are_readable_and_safe():
    assert sweep.folder_name(
        [("geometry.stenosis_degree", "0.5"), ("geometry.cap_thickness", "5.0e-4")]
    ) == ("geometry.stenosis_degree=0.5,geometry.cap_thickness=5.0e-4")
    assert sweep.folder_name([("geometry.plaque_sides", "[bottom, top]")]) == (
        "geometry.plaque_sides=bottom_top"
    )
    assert "/" not in sweep.folder_name([("name", "a/../b")])


# --------------------------------------------------------------------------------------------
# Runs


def test_a_sweep_tables_its_runs_and_a_rerun_skips_them(shared_tmp, capsys):
    out = shared_tmp / "sweep"
    vary = ["--vary", "geometry.stenosis_degree=0.4,0.5", "--vary", "geometry.cap_thickness=5.0e-4"]
    assert sweep_main(STENOSIS, out, *vary, *TWO_STEPS) == 0
    err = rank0_stderr(capsys)
    assert "sweep 1/2: geometry.stenosis_degree=0.4, geometry.cap_thickness=5.0e-4: started" in err
    assert "sweep 2/2: geometry.stenosis_degree=0.5, geometry.cap_thickness=5.0e-4: done in" in err

    table = read_table(out)
    assert [
        (r["geometry.stenosis_degree"], r["geometry.cap_thickness"], r["status"]) for r in table
    ] == [("0.4", "5.0e-4", "done"), ("0.5", "5.0e-4", "done")]
    for row, degree in zip(table, ("0.4", "0.5"), strict=True):
        run = out / f"geometry.stenosis_degree={degree},geometry.cap_thickness=5.0e-4"
        summary = json.loads((run / "summary.json").read_text())
        metrics = metrics_csv.read_metrics(run / "metrics.csv")
        assert summary["end_time_s"] == pytest.approx(0.0005) and len(metrics) == 2
        expected = {
            "min_tawss": summary["min_tawss"],
            "max_osi": summary["max_osi"],
            "max_principal_cap": max(r["max_principal_cap"] for r in metrics),
            "max_sss": max(r["max_sss"] for r in metrics),
            "min_wss": min(r["min_wss"] for r in metrics),
            "max_wss": max(r["max_wss"] for r in metrics),
            "max_recirculation_length": max(r["recirculation_length"] for r in metrics),
            "peak_displacement": max(r["peak_displacement"] for r in metrics),
            "peak_inlet_flow_rate": max(r["inlet_flow_rate"] for r in metrics),
        }
        for name, value in expected.items():  # the CSV keeps 10 significant digits
            assert float(row[name]) == pytest.approx(value, rel=1e-9, abs=0), name
        assert float(row["max_principal_cap"]) > 0 and float(row["peak_displacement"]) > 0
    # The narrower lumen: a stronger jet, more stress in the cap.
    assert float(table[1]["max_principal_cap"]) > float(table[0]["max_principal_cap"])
    md = (out / "sweep.md").read_text()
    assert "| 0.4 | 5.0e-4 |" in md and "| 0.5 | 5.0e-4 |" in md
    for name in ("max_principal_cap", "max_sss", "max_osi", "peak_inlet_flow_rate"):
        assert (out / f"sweep_{name}.png").stat().st_size > 1000

    # Again: every run is finished, so nothing is recomputed (no run file touched).
    before = MPI.COMM_WORLD.bcast(stamps(out) if MPI.COMM_WORLD.rank == 0 else None)
    assert sweep_main(STENOSIS, out, *vary, *TWO_STEPS) == 0
    assert rank0_stderr(capsys).count("done earlier, skipped") == 2
    after = stamps(out)
    runs = [p for p in before if "sweep" not in p.rsplit("/", 1)[-1]]
    assert runs and all(after[p] == before[p] for p in runs)
    assert read_table(out) == table


def test_a_longer_time_end_resumes_each_run_from_its_checkpoint(shared_tmp, capsys):
    out = shared_tmp / "sweep"
    vary = ["--vary", "fluid.rheology.viscosity=0.0035,0.004"]
    assert sweep_main(CHANNEL, out, *vary, "--set", "time.end=0.002") == 0
    capsys.readouterr()
    longer = ["--set", "time.end=0.003"]
    before = MPI.COMM_WORLD.bcast(stamps(out) if MPI.COMM_WORLD.rank == 0 else None)
    assert sweep_main(CHANNEL, out, *vary, *longer, "--dry-run") == 0  # says, writes nothing
    said = MPI.COMM_WORLD.bcast(capsys.readouterr().out, root=0)
    assert said.count("would be resumed from its checkpoint at t = 0.002 s") == 2
    assert stamps(out) == before
    assert sweep_main(CHANNEL, out, *vary, *longer) == 0
    assert rank0_stderr(capsys).count("resumed from its checkpoint at t = 0.002 s") == 2
    for viscosity in ("0.0035", "0.004"):
        run = out / f"fluid.rheology.viscosity={viscosity}"
        assert [r["step"] for r in metrics_csv.read_metrics(run / "metrics.csv")] == [1, 2, 3]
        assert json.loads((run / "summary.json").read_text())["end_time_s"] == pytest.approx(0.003)
    table = read_table(out)
    assert [r["status"] for r in table] == ["done", "done"]
    # A rigid channel has no structure: its structure's columns are empty, not 0.
    assert all(
        r["max_principal_cap"] == r["max_sss"] == r["peak_displacement"] == "" for r in table
    )
    assert all(float(r["peak_inlet_flow_rate"]) > 0 for r in table)
    # The thicker blood flows less under the same pressure.
    assert float(table[1]["peak_inlet_flow_rate"]) < float(table[0]["peak_inlet_flow_rate"])

    # What is not this run is started afresh: another schedule to the same end, another key.
    for changed, why in [
        (
            "time.schedule=[{until: 0.1, dt: 5.0e-4}]",
            "started afresh (it ran to time.end with another schedule)",
        ),
        (
            "fluid.density=1000",
            "started afresh (its folder holds a run with another fluid.density)",
        ),
    ]:
        assert sweep_main(CHANNEL, out, *vary, *longer, "--set", changed, "-n") == 0
        said = MPI.COMM_WORLD.bcast(capsys.readouterr().out, root=0)
        assert said.count(f"would be {why}") == 2, said


def test_a_failed_run_is_recorded_and_the_sweep_goes_on(shared_tmp, capsys):
    out = shared_tmp / "sweep"
    status = sweep_main(
        CHANNEL,
        out,
        "--vary",
        "fluid.solver.max_iterations=1,25",
        "--set",
        "time.end=0.002",
        "--set",
        "time.retries=0",
    )
    assert status == 3
    first, second = read_table(out)
    assert first["status"].startswith("failed: solve failed: fluid step to t = 0.001 s")
    assert first["min_wss"] == first["peak_inlet_flow_rate"] == ""  # no numbers for it
    assert second["status"] == "done" and float(second["peak_inlet_flow_rate"]) > 0
    assert "Traceback" not in rank0_stderr(capsys)


def test_a_stop_signal_stops_the_run_and_the_sweep_which_resumes(shared_tmp, capsys):
    """SIGUSR1 during the first run (sent by each rank to itself once the run has written a
    step): the run stops after its step with a checkpoint, the sweep after it (exit 138),
    with the table so far and the command that resumes it; that command finishes the sweep."""
    out = shared_tmp / "sweep"
    options = [
        "--vary",
        "fluid.rheology.viscosity=0.0035,0.004",
        "--set",
        "time.end=10",
        "--set",
        "time.schedule=[{until: 10, dt: 0.001}]",
    ]
    first = out / "fluid.rheology.viscosity=0.0035" / "metrics.csv"

    def signal_after_a_step() -> None:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            if first.is_file() and len(first.read_text().splitlines()) >= 3:
                os.kill(os.getpid(), signal.SIGUSR1)
                return
            time.sleep(0.05)

    sender = threading.Thread(target=signal_after_a_step, daemon=True)
    sender.start()
    status = sweep_main(CHANNEL, out, *options)
    sender.join()
    assert status == 128 + signal.SIGUSR1
    err = rank0_stderr(capsys)
    assert "Traceback" not in err
    assert "sweep 1/2: fluid.rheology.viscosity=0.0035: stopped after" in err
    resume = (
        f"fsi sweep {CHANNEL} --out {out} --vary fluid.rheology.viscosity=0.0035,0.004 "
        "--set time.end=10 --set 'time.schedule=[{until: 10, dt: 0.001}]'"
    )
    assert f"To resume it, run\n  {resume}" in err
    assert [r["status"] for r in read_table(out)] == ["stopped", "pending"]
    last = int(max(r["step"] for r in metrics_csv.read_metrics(first)))
    assert last >= 2 and not (out / "fluid.rheology.viscosity=0.004").exists()

    # The command resumes the stopped run from its checkpoint (here with a nearer end).
    shorter = [*options[:2], "--set", f"time.end={round((last + 2) * 0.001, 6)}", *options[4:]]
    assert sweep_main(CHANNEL, out, *shorter) == 0
    assert f"viscosity=0.0035: resumed from its checkpoint at t = {last * 0.001:.6g} s" in (
        rank0_stderr(capsys)
    )
    assert [r["step"] for r in metrics_csv.read_metrics(first)] == list(range(1, last + 3))
    assert [r["status"] for r in read_table(out)] == ["done", "done"]


def test_a_stop_between_runs_ends_the_sweep_before_the_next(shared_tmp, capsys):
    """A signal that comes while no run is stepping (the check before each run)."""
    out = shared_tmp / "sweep"
    variations = sweep.parse_vary(["fluid.rheology.viscosity=0.0035,0.004"])
    runs = sweep.plan(CHANNEL, variations, [], out)
    started = []

    def run_one(run, resume, overwrite):
        started.append(run.index)
        return 0, ""

    status = sweep_execution.execute(
        runs, variations, out, run_one, lambda: signal.SIGTERM, ["fsi", "sweep", "..."]
    )
    assert status == 128 + signal.SIGTERM and started == []
    assert [r["status"] for r in read_table(out)] == ["pending", "pending"]
    assert "To resume it, run\n  fsi sweep ..." in rank0_stderr(capsys)


# --------------------------------------------------------------------------------------------
# Refused before any run


BAD = [
    (
        ["--vary", "geometry.stenosis_degree=0.4,1.5"],
        "--vary geometry.stenosis_degree=1.5: geometry.stenosis_degree: expected a number in "
        "(0.0, 1.0), got 1.5",
    ),
    (
        ["--vary", "geometry.stenosis_degre=0.4"],
        "--vary geometry.stenosis_degre=0.4: geometry.stenosis_degre: expected one of the keys",
    ),
    (
        ["--vary", "geometry.cap_thickness=5e-4,0.004"],
        "--vary geometry.cap_thickness=0.004: geometry.cap_thickness: expected less than the "
        "plaque height",
    ),
    (
        ["--vary", "geometry.stenosis_degree=0.2", "--vary", "geometry.cap_thickness=5e-4"],
        "--vary geometry.stenosis_degree=0.2, geometry.cap_thickness=5e-4: geometry.lipid_length",
    ),
    (
        ["--vary", "structure.degree=2,1"],
        "--vary structure.degree=1: structure.degree: the coupling pairs",
    ),
    (
        ["--vary", "geometry.stenosis_degree=0.4", "--vary", "geometry.stenosis_degree=0.5"],
        "--vary geometry.stenosis_degree: given twice (list all its values in one --vary)",
    ),
    (
        ["--vary", "geometry.stenosis_degree="],
        "--vary geometry.stenosis_degree: no values (expected geometry.stenosis_degree=value1,",
    ),
    (
        ["--vary", "geometry.stenosis_degree=0.4,,0.5"],
        "--vary geometry.stenosis_degree: an empty value in '0.4,,0.5'",
    ),
    (
        ["--vary", "geometry.stenosis_degree=0.4,0.4"],
        "--vary geometry.stenosis_degree: the value '0.4' is given twice",
    ),
    (
        ["--vary", "geometry.stenosis_degree=0.4,0.40"],
        "--vary: geometry.stenosis_degree=0.4 and geometry.stenosis_degree=0.40 are the same case",
    ),
    (["--vary", "stenosis_degree"], "--vary 'stenosis_degree': expected key.path=value1,"),
    (
        ["--vary", "geometry.stenosis_degree=0.4", "--set", "geometry.stenosis_degree=0.5"],
        "--vary geometry.stenosis_degree: also given with --set: vary it or set it, not both",
    ),
    (
        ["--vary", "geometry.stenosis_degree=0.4", "--set", "geometry={stenosis_degree: 0.5}"],
        "--vary geometry.stenosis_degree: also given with --set (as part of geometry)",
    ),
    (
        [
            "--vary",
            "name=" + ",".join(f"n{i}" for i in range(40)),
            "--vary",
            "fluid.density=" + ",".join(str(1000 + i) for i in range(40)),
        ],
        "--vary: 40 x 40 = 1600 runs; a sweep runs at most 1000",
    ),
    (
        ["--vary", "geometry.stenosis_degree=0.4", "--set", "fluid.density=-1"],
        "--set: fluid.density: expected a positive number",
    ),
]


@pytest.mark.parametrize("options, message", BAD, ids=[m[:40] for _, m in BAD])
def test_bad_input_exits_2_naming_the_key_before_any_run(shared_tmp, capsys, options, message):
    out = shared_tmp / "sweep"
    assert sweep_main(STENOSIS, out, *options) == 2
    err = rank0_stderr(capsys)
    assert err.startswith(f"fsi: error: {message}"), err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_an_out_that_is_a_file_exits_2(shared_tmp, capsys):
    out = shared_tmp / "file"
    if MPI.COMM_WORLD.rank == 0:
        out.write_text("not a folder")
    MPI.COMM_WORLD.barrier()
    assert sweep_main(CHANNEL, out, "--vary", "fluid.density=1000,1060") == 2
    assert rank0_stderr(capsys) == f"fsi: error: --out: {out} is a file, not a folder\n"


def test_sweep_plots_name_the_quantities_and_their_units():
    """The x-axis names the varied quantity and its unit as the config declares it, the y-axis
    the headline's quantity (its unit is chosen from the values): not config keys."""
    case = config.load("configs/stenosis_moving_newtonian.yaml")
    assert sweep_results.axis_label(case, "geometry.cap_thickness") == "cap thickness (m)"
    assert sweep_results.axis_label(case, "geometry.stenosis_degree") == "stenosis degree"
    assert sweep_results.axis_label(case, "fluid.inlet.amplitude") == "inlet amplitude (Pa)"
    assert sweep_results.axis_label(case, "structure.cap.young_modulus") == "cap young modulus (Pa)"
    assert sweep_results.axis_label(case, "fluid.rheology.viscosity") == "rheology viscosity (Pa s)"
    assert sweep_results.axis_label(case, "mesh.level") == "mesh level"
    labels = [h.label for h in sweep_results.HEADLINES]
    assert len(set(labels)) == len(labels) and all("_" not in label for label in labels)


def test_ctrl_c_while_a_sweep_is_validated_is_one_line_and_exit_130(
    shared_tmp, capsys, monkeypatch
):
    """Ctrl-C outside a run's steps (here while the sweep's runs are validated): one line, no
    traceback, exit status 128 + SIGINT, nothing written."""

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep, "plan", interrupted)
    out = shared_tmp / "interrupted"
    capsys.readouterr()
    assert sweep_main(STENOSIS, out, "--vary", "geometry.stenosis_degree=0.4,0.5") == 130
    assert capsys.readouterr().err == "fsi: interrupted\n"
    assert not out.exists()


def test_varied_inlets_are_validated_with_the_cycles_they_make_possible(shared_tmp, capsys):
    """``--set time.cycles=2`` needs a periodic inlet: the base case's pulse has none, the
    varied inlets have; each combination is validated, not the base (a dry run lists both).
    Where no combination fixes it, the base's error is the message."""
    inlets = ",".join(
        f"{{kind: pressure_table, table: [[0.0, 0.0], [0.002, {peak}], [0.004, 0.0]], "
        "period: 0.004}"
        for peak in (100.0, 200.0)
    )
    out = shared_tmp / "inlets"
    capsys.readouterr()
    vary = ["--vary", f"fluid.inlet={inlets}", "--set", "time.cycles=2", "--set", "time.end=0.004"]
    vary.append("--dry-run")
    assert sweep_main(STENOSIS, out, *vary) == 0
    listed = MPI.COMM_WORLD.bcast(capsys.readouterr().out, root=0)
    assert [line.split(":")[0] for line in listed.splitlines()] == ["sweep 1/2", "sweep 2/2"]
    assert sweep_main(STENOSIS, out, "--vary", "geometry.stenosis_degree=0.4,0.5",
                      "--set", "time.cycles=2", "--dry-run") == 2  # fmt: skip
    assert "time.cycles" in rank0_stderr(capsys)


def test_a_sweep_never_deletes_results_without_overwrite_nor_through_a_link(shared_tmp, capsys):
    """Finished runs to 2 ms. The same sweep to 1 ms is covered by them: skipped, nothing
    touched, the table from their rows up to 1 ms. With another ``--set`` the runs would
    replace them: refused (exit 2, naming how many and the first, with why), nothing touched,
    unless ``--overwrite``. A run folder that is a symbolic link to another folder is refused
    even with ``--overwrite``, and what it points to is left alone."""
    import os

    comm = MPI.COMM_WORLD
    out = shared_tmp / "sweep"
    vary = ["--vary", "fluid.rheology.viscosity=0.0035,0.004"]
    assert sweep_main(CHANNEL, out, *vary, "--set", "time.end=0.002") == 0
    longer = read_table(out)
    runs = comm.bcast(stamps(out) if comm.rank == 0 else None)
    runs = {path: stamp for path, stamp in runs.items() if "/fluid." in path}
    capsys.readouterr()
    assert sweep_main(CHANNEL, out, *vary, "--set", "time.end=0.001") == 0
    err = rank0_stderr(capsys)
    assert err.count("done earlier to t = 0.002 s, which covers time.end = 0.001 s") == 2, err
    assert {path: stamp for path, stamp in stamps(out).items() if path in runs} == runs
    shorter = read_table(out)
    for row, run in zip(shorter, longer):
        assert row["status"] == "done"
        assert float(row["peak_inlet_flow_rate"]) < float(run["peak_inlet_flow_rate"])
        assert row["min_tawss"] == ""  # summary.json's, over the whole 2 ms: not tabled
    capsys.readouterr()
    assert sweep_main(CHANNEL, out, *vary, "--set", "time.end=0.002", "--set",
                      "fluid.density=1000") == 2  # fmt: skip
    err = rank0_stderr(capsys)
    assert "2 of the 2 runs would delete an earlier run's results" in err, err
    assert "add --overwrite to replace them" in err
    assert {path: stamp for path, stamp in stamps(out).items() if path in runs} == runs
    changed = [*vary, "--set", "time.end=0.001", "--set", "fluid.density=1000"]
    assert sweep_main(CHANNEL, out, *changed, "--overwrite") == 0
    run = out / "fluid.rheology.viscosity=0.004"
    assert [r["step"] for r in metrics_csv.read_metrics(run / "metrics.csv")] == [1]

    elsewhere = shared_tmp / "elsewhere"
    if comm.rank == 0:
        os.rename(run, elsewhere)
        os.symlink(elsewhere, run)
    comm.barrier()
    kept = comm.bcast(stamps(elsewhere) if comm.rank == 0 else None)
    for extra in ([], ["--overwrite"]):
        capsys.readouterr()
        assert sweep_main(CHANNEL, out, *vary, "--set", "time.end=0.003", *extra) == 2
        assert "is a symbolic link (to " in rank0_stderr(capsys)
    assert stamps(elsewhere) == kept


def test_a_long_validation_says_how_far_it_is(shared_tmp, capsys, monkeypatch):
    """A sweep's runs are validated before the first starts (a thousand take seconds): a
    progress line comes every VALIDATION_PROGRESS_S seconds (here: at every run)."""
    monkeypatch.setattr(sweep, "VALIDATION_PROGRESS_S", -1.0)
    vary = ["--vary", "fluid.density=1000,1001,1002", "--dry-run"]
    assert sweep_main(STENOSIS, shared_tmp / "progress", *vary) == 0
    err = rank0_stderr(capsys)
    assert [line for line in err.splitlines() if "validated" in line] == [
        "sweep: validated 1 of 3 runs",
        "sweep: validated 2 of 3 runs",
    ]


def test_a_sweep_plot_title_fits_its_figure():
    """The headline's meaning as a one-panel plot's title (5 inches) was cut off at both
    edges: each headline's title now lies within the figure, on as many lines as it takes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for h in sweep_results.HEADLINES:
        figure, axes = plt.subplots(1, 1, figsize=(5.0, 3.8), squeeze=False)
        sweep_results.suptitle(figure, h.meaning)
        figure.tight_layout()
        figure.canvas.draw()
        box = figure._suptitle.get_window_extent(figure.canvas.get_renderer())
        width, height = figure.bbox.width, figure.bbox.height
        plt.close(figure)
        assert 0 <= box.x0 and box.x1 <= width and box.y1 <= height, (h.name, box, width)
