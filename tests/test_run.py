"""``fsi run`` end to end on a short rigid-structure stenosis case: files, columns, 1 = N ranks."""

import json
import shlex
import sys
import time
from pathlib import Path

from mpi4py import MPI

import dolfinx
import numpy as np
import pytest

import fsi
from fsi import cli, config
from fsi.output import io, metrics_csv, provenance
from fsi.run import errors, simulation

SHORT = ["structure.mode=rigid", "time.end=0.004", "time.schedule=[{until: 0.004, dt: 0.001}]"]
CASE = "configs/stenosis_fixed_newtonian.yaml"


def test_rigid_run_writes_the_contract_files(shared_tmp):
    out = shared_tmp / "run"
    assert cli.main(["run", CASE, "--out", str(out), *sum((["--set", s] for s in SHORT), [])]) == 0
    rows = metrics_csv.read_metrics(out / "metrics.csv")
    assert [r["step"] for r in rows] == [1, 2, 3, 4]
    for column in (
        "step",
        "t",
        "dt",
        "peak_velocity",
        "peak_pressure",
        "peak_displacement",
        "coupling_iterations",
        "wall_time_s",
    ):
        assert column in rows[0]
    assert rows[-1]["t"] == pytest.approx(0.004)
    # The pulse (peak 1200 Pa at t = 2.5 ms) accelerates the blood: velocity grows while it acts.
    assert 0 < rows[0]["peak_velocity"] < rows[1]["peak_velocity"] < rows[3]["peak_velocity"]
    assert 0 < max(r["peak_pressure"] for r in rows) <= 1200 * 1.01
    summary = json.loads((out / "summary.json").read_text())
    assert summary["steps"] == 4 and summary["ranks"] == MPI.COMM_WORLD.size
    # Provenance: versions, the git revision of this checkout, the process's command line.
    assert summary["fsi"] == fsi.__version__ and summary["dolfinx"] == dolfinx.__version__
    assert summary["blas"] == provenance.blas_library()
    assert summary["git"] is None or len(summary["git"].removesuffix("+dirty")) == 40
    assert summary["command"] == shlex.join(sys.argv)
    log = (out / "run.log").read_text().splitlines()  # the header, a line per step, the end
    assert f"fsi {fsi.__version__}" in log[0]
    assert [line.split()[3] for line in log[1:5]] == ["1/4", "2/4", "3/4", "4/4"]
    assert "done: 4 steps" in log[-1]
    assert config.load(out / "config.yaml").structure.mode == "rigid"
    fields = (out / "fields.xdmf").read_text()
    for name in ("velocity", "pressure", "viscosity", "shear_rate", "wall_shear_stress"):
        assert f'Name="{name}"' in fields, name
    # Forward flow along the walls while the pulse acts: τ_w > 0 at the throat, no reversal.
    assert all(r["max_wss"] > 0 and r["recirculation_length"] >= 0 for r in rows)
    # Flow rates (m²/s per unit depth, positive downstream): the pulse drives the blood
    # forward, and with rigid no-slip walls what enters leaves. Taylor–Hood conserves mass
    # only weakly (∫ q div u dx = 0 for the P1 q, not div u = 0 pointwise), but q = 1 is one
    # of those q, so Q_out − Q_in = ∫ div u dx = 0 up to the linear solve: these rows are
    # linear in u, so every Newton iterate meets them whatever the momentum residual left.
    # Measured: equal to all 10 digits metrics.csv keeps (1 and 2 ranks). 1e-8 relative
    # allows the CSV's rounding and an iterative linear solver, not a leak.
    for r in rows:
        assert np.isfinite(r["inlet_flow_rate"]) and np.isfinite(r["outlet_flow_rate"])
        assert r["inlet_flow_rate"] > 0
        assert abs(r["inlet_flow_rate"] - r["outlet_flow_rate"]) < 1e-8 * r["inlet_flow_rate"]
    assert rows[0]["inlet_flow_rate"] < rows[1]["inlet_flow_rate"] < rows[3]["inlet_flow_rate"]


def test_serial_and_parallel_runs_agree(shared_tmp):
    comm = MPI.COMM_WORLD
    case = config.load(CASE, SHORT)
    world = simulation.run(case, shared_tmp / "world", comm)
    alone = simulation.run(case, shared_tmp / f"self{comm.rank}", MPI.COMM_SELF)
    assert world.steps == alone.steps
    rows_world = metrics_csv.read_metrics(shared_tmp / "world" / "metrics.csv")
    rows_self = metrics_csv.read_metrics(shared_tmp / f"self{comm.rank}" / "metrics.csv")
    for a, b in zip(rows_world, rows_self):
        assert a["peak_velocity"] == pytest.approx(b["peak_velocity"], rel=1e-8)
        assert a["peak_pressure"] == pytest.approx(b["peak_pressure"], rel=1e-8)


@pytest.mark.parametrize(
    "config_file, overrides, message",
    [
        # The interface maps pair P2 nodes of the fluid and the structure.
        (CASE, ["structure.degree=3"], "needs structure.degree 2"),
    ],
)
def test_unsupported_coupled_cases_are_refused_before_any_work(
    shared_tmp, capsys, config_file, overrides, message
):
    out = shared_tmp / "refused"
    assert (
        cli.main(
            ["run", config_file, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
        )
        == 2
    )
    assert not out.exists()
    if MPI.COMM_WORLD.rank == 0:
        assert message in capsys.readouterr().err


def test_rigid_stenosis_stays_stable_after_the_pulse(shared_tmp):
    """With the plain traction condition σ n = −P n the jet blew up at t ≈ 0.031 s (|u| 0.24 →
    2 m/s in 9 ms, then Newton diverged), growing at the inlet's corners, where that condition
    lets tangential velocity in. The study's normal-flow inlet (docs/boundary-conditions.md)
    keeps the decaying flow decaying."""
    out = shared_tmp / "stable"
    overrides = [
        "structure.mode=rigid",
        "time.end=0.06",
        "time.schedule=[{until: 0.005, dt: 5.0e-4}, {until: 0.06, dt: 1.0e-3}]",
    ]
    assert (
        cli.main(["run", CASE, "--out", str(out), *sum((["--set", s] for s in overrides), [])]) == 0
    )
    rows = metrics_csv.read_metrics(out / "metrics.csv")
    after = [r["peak_velocity"] for r in rows if r["t"] >= 0.01]
    assert rows[-1]["t"] == pytest.approx(0.06)
    assert all(b <= a * 1.001 for a, b in zip(after, after[1:])), "the flow must keep slowing down"


def test_a_stenosis_with_plaque_on_both_sides_runs_in_every_mode(shared_tmp):
    """``geometry.plaque_sides: [bottom, top]`` leaves no rigid wall: the lumen is bounded by
    the interface alone (every run stopped on the missing no-slip tag before). Through the
    pulse's first millisecond the fixed wall (moving ~10 nm) has the rigid plaque's pressure
    (to 3e-6; its velocity differs by a few per cent there, as with one plaque: the wall's
    ~4e-5 m/s is not small beside the blood's first 1e-3 m/s)."""
    rows = {}
    for mode in ("rigid", "fixed_wall", "moving_wall"):
        overrides = [
            f"structure.mode={mode}",
            "geometry.plaque_sides=[bottom, top]",
            "time.end=0.001",
            "time.schedule=[{until: 0.001, dt: 2.5e-4}]",
        ]
        args = ["run", CASE, "--out", str(shared_tmp / mode)]
        assert cli.main(args + sum((["--set", s] for s in overrides), [])) == 0, mode
        rows[mode] = metrics_csv.read_metrics(shared_tmp / mode / "metrics.csv")
        assert [r["step"] for r in rows[mode]] == [1, 2, 3, 4]
    for rigid, fixed in zip(rows["rigid"], rows["fixed_wall"]):
        assert fixed["peak_pressure"] == pytest.approx(rigid["peak_pressure"], rel=1e-4)
    assert rows["moving_wall"][-1]["peak_wall_displacement"] > 0.0


def test_structure_alone_under_the_inlet_pressure(shared_tmp):
    """structure.interface_load: inlet_pressure — the study's structure under P(t), no fluid."""
    peaks = {}
    for mode in ("fixed_wall", "moving_wall"):
        out = shared_tmp / mode
        overrides = [
            f"structure.mode={mode}",
            "structure.interface_load=inlet_pressure",
            "time.end=0.003",
            "time.schedule=[{until: 0.003, dt: 5.0e-4}]",
        ]
        args = ["run", CASE, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
        assert cli.main(args) == 0
        rows = metrics_csv.read_metrics(out / "metrics.csv")
        assert len(rows) == 6 and all(r["max_sss"] > 0 for r in rows)
        assert rows[-1]["peak_pressure"] == pytest.approx(600 * (1 - np.cos(2 * np.pi * 0.6)))
        peaks[mode] = max(r["peak_displacement"] for r in rows)
        walls = [r["peak_wall_displacement"] for r in rows]
        assert (max(walls) == 0.0) == (mode == "fixed_wall")  # the wall is held in fixed_wall
        assert "sss" in (out / "solid.xdmf").read_text()
    assert 0 < peaks["fixed_wall"] < peaks["moving_wall"] / 100


@pytest.mark.parametrize(
    "overrides,expected",
    [
        (["structure.mode=rigid", "structure.interface_load=none"], "no structure to load"),
        (
            ["fluid.inlet={kind: parabolic_velocity}", "structure.interface_load=inlet_pressure"],
            "needs a traction inlet",
        ),
    ],
)
def test_interface_load_needs_a_structure_and_a_pressure(overrides, expected):
    with pytest.raises(config.ConfigError, match=expected):
        config.load(CASE, overrides)


class HalfStepOnly:
    """A stepper whose solve fails for steps longer than ``limit`` (a
    :class:`fsi.run.steppers.Stepper` as far as :func:`simulation.advance` uses it): its state is
    the time it has reached."""

    def __init__(self, limit: float):
        self.limit, self.t, self.taken = limit, 0.0, []

    def step(self, step):
        if step.dt > self.limit * (1 + 1e-12):
            self.t = float("nan")  # a failed solve leaves garbage behind
            raise errors.StepFailed(f"dt = {step.dt} is too long")
        assert step.t - step.dt == pytest.approx(self.t)  # continues from where it is
        self.t = step.t
        self.taken.append(step.dt)
        return {"reached": self.t}

    def state(self):
        return {"t": np.array(self.t)}

    def load_state(self, state):
        self.t = float(state["t"])


def test_a_failed_step_is_retried_as_halves_from_the_state_before_it():
    """time.retries: a failed step goes back to the state before it and is taken as two halves,
    each of which may be halved again while retries remain."""
    from fsi.numerics.timestepping import Step

    stepper, retried = HalfStepOnly(limit=0.1), []
    row = simulation.advance(stepper, Step(3, 0.4, 0.4), stepper.state(), 2, retried)
    assert stepper.taken == pytest.approx([0.1] * 4) and row == {"reached": pytest.approx(0.4)}
    assert [(s.index, s.dt) for s in retried] == [(3, 0.4), (3, 0.2), (3, 0.2)]
    # One retry is not enough: the failure is raised (march then checkpoints the state before).
    stepper = HalfStepOnly(limit=0.1)
    with pytest.raises(errors.StepFailed, match="too long"):
        simulation.advance(stepper, Step(1, 0.4, 0.4), stepper.state(), 1, [])
    # No retries: the first failure ends it, as before time.retries existed.
    with pytest.raises(errors.StepFailed):
        simulation.advance(HalfStepOnly(0.1), Step(1, 0.2, 0.2), {"t": np.array(0.0)}, 0, [])


def test_retries_are_validated():
    with pytest.raises(config.ConfigError, match="time.retries"):
        config.from_dict({"time": {"retries": -1}})


def test_structure_alone_turek_hron_writes_point_a(shared_tmp):
    """A CSM run (``structure.interface_load: none``) writes the benchmark's ``ux_A``, ``uy_A``
    as the FSI runs do: the flag sags under gravity (quasi-static: at rest from step 1, near the
    reference u_y(A) = −66.10 mm, reference/turek_hron.md), the same on all ranks and on one."""
    comm = MPI.COMM_WORLD
    case = config.load("configs/turek_hron_csm1.yaml", ["time.end=0.1"])  # 2 steps of 0.05 s
    simulation.run(case, shared_tmp / "world", comm)
    simulation.run(case, shared_tmp / f"self{comm.rank}", MPI.COMM_SELF)
    world = metrics_csv.read_metrics(shared_tmp / "world" / "metrics.csv")
    alone = metrics_csv.read_metrics(shared_tmp / f"self{comm.rank}" / "metrics.csv")
    assert [r["step"] for r in world] == [r["step"] for r in alone] == [1, 2]
    for a, b in zip(world, alone):
        assert a["uy_A"] < 0 and a["ux_A"] < 0
        for key in ("ux_A", "uy_A"):
            assert a[key] == pytest.approx(b[key], rel=1e-8), key
    assert world[-1]["uy_A"] == pytest.approx(-66.10e-3, rel=0.01)
    assert world[-1]["ux_A"] == pytest.approx(-7.187e-3, rel=0.01)


def test_version(capsys):
    assert cli.main(["--version"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"fsi {fsi.__version__}") and f"dolfinx {dolfinx.__version__}" in out
    assert f"BLAS {provenance.blas_name(provenance.blas_library())}" in out


def test_the_blas_under_mumps_is_named_and_the_setup_gives_an_optimised_one():
    assert provenance.blas_name("/usr/lib/x86_64-linux-gnu/blas/libblas.so.3.11.0") == "reference"
    assert provenance.blas_name("/usr/lib/aarch64-linux-gnu/openblas-pthread/libblas.so.3") == (
        "openblas-pthread"
    )
    assert provenance.blas_name(None) == "unknown"
    # scripts/setup installs Debian's libopenblas0-serial (scripts/debian-packages.txt), whose
    # update-alternatives priority puts it before the reference BLAS that PETSc's Debian build
    # would otherwise load: MUMPS's factorisations 3.6x faster at the fine level.
    library = provenance.blas_library()
    assert library is not None and Path(library).is_file()
    assert provenance.blas_name(library) == "openblas-serial", library


@pytest.mark.parametrize(
    "command",
    [["run", CASE], ["mesh", CASE], ["sweep", CASE, "--vary", "fluid.density=1000"]],
)
def test_an_empty_out_is_refused(command, shared_tmp, monkeypatch, capsys):
    """``--out ""`` would write into the current directory: refused (exit 2, naming --out),
    nothing written."""
    here = shared_tmp / f"cwd-{command[0]}"
    if MPI.COMM_WORLD.rank == 0:
        here.mkdir()
    MPI.COMM_WORLD.barrier()
    absolute = [str(Path(part).absolute()) if part == CASE else part for part in command]
    monkeypatch.chdir(here)
    assert cli.main([*absolute, "--out", ""]) == 2
    assert "argument --out: expected a path, not an empty string" in capsys.readouterr().err
    assert list(here.iterdir()) == []


def test_a_second_run_into_a_folder_being_written_is_refused(shared_tmp, capsys):
    """While a run holds ``--out`` (its ``run.lock``), another ``fsi run`` into it, even with
    ``--overwrite``, is refused with exit 2 naming the holder's process id, and writes nothing;
    once the holder lets go, the folder can be written."""
    import os

    out = shared_tmp / "busy"
    short = ["--set", "structure.mode=rigid", "--set", "time.end=0.001"]
    holder = MPI.COMM_WORLD.bcast(os.getpid())
    with io.RunLock(MPI.COMM_WORLD, out):
        capsys.readouterr()
        for extra in ([], ["--overwrite"]):
            assert cli.main(["run", CASE, "--out", str(out), *short, *extra]) == 2
            if MPI.COMM_WORLD.rank == 0:
                err = capsys.readouterr().err
                assert f"is being written by another fsi run (process {holder}," in err, err
        assert sorted(p.name for p in out.iterdir()) == ["run.lock"]
    assert cli.main(["run", CASE, "--out", str(out), *short]) == 0
    assert (out / "summary.json").is_file()


def test_paths_the_file_system_cannot_name_exit_2_naming_the_option(shared_tmp, capsys):
    """A name in a path over 255 bytes, or a path over PATH_MAX, made every command that opens
    it end with OSError [Errno 36], a traceback and exit 1: now each is refused as a wrong
    argument (exit 2, naming the option and the limit) before anything is read or written."""
    comm = MPI.COMM_WORLD
    long_name = shared_tmp / ("a" * 300)
    deep = shared_tmp.joinpath(*["b" * 200] * 21)  # each name allowed, the whole > 4096 bytes
    commands = {
        "--out": [
            ["run", CASE, "--out", str(long_name)],
            ["mesh", CASE, "--out", str(long_name)],
            ["report", str(shared_tmp), "--out", str(long_name)],
            ["sweep", CASE, "--vary", "mesh.size=1e-3", "--out", str(long_name)],
            [
                "plot",
                str(shared_tmp),
                "--field",
                "velocity",
                "--time",
                "0",
                "--out",
                f"{long_name}.png",
            ],
            ["run", CASE, "--out", str(deep)],
        ],  # fmt: skip
        "--restart": [["run", "--restart", str(long_name), "--out", str(shared_tmp / "r")]],
        "RUN_DIR": [["report", str(long_name)], ["plot", str(deep), "--field", "velocity"]],
    }
    for option, argvs in commands.items():
        for argv in argvs:
            capsys.readouterr()
            start = time.perf_counter()
            assert cli.main(argv) == 2, argv
            assert time.perf_counter() - start < 5, argv
            err = capsys.readouterr().err
            assert "Traceback" not in err and f"error: argument {option}: the " in err, err
            assert "255 bytes a file name may have" in err or "(PATH_MAX 4096" in err, err
    assert sorted(p.name for p in shared_tmp.iterdir()) == []  # nothing written
    comm.barrier()


def test_paths_that_cannot_hold_the_output_exit_2_not_4(shared_tmp, capsys):
    """A dangling symbolic link as ``--out``, and ``fsi report --out`` at a file or below one:
    exit 2 naming the path and what is wrong (not 4, "could not write"), nothing written.
    ``--overwrite`` with a symbolic link among the earlier run's files removes the link and
    leaves what it points to alone."""
    import os

    comm = MPI.COMM_WORLD
    short = ["--set", "structure.mode=rigid", "--set", "time.end=0.001"]
    dangling = shared_tmp / "dangling"
    if comm.rank == 0:
        os.symlink(shared_tmp / "nowhere", dangling)
    comm.barrier()
    capsys.readouterr()
    assert cli.main(["run", CASE, "--out", str(dangling), *short]) == 2
    if comm.rank == 0:
        assert (
            f"--out: {dangling} is a symbolic link to {shared_tmp / 'nowhere'}, which does not "
            "exist" in capsys.readouterr().err
        )
    assert not (shared_tmp / "nowhere").exists()
    run = shared_tmp / "run"
    assert cli.main(["run", CASE, "--out", str(run), *short]) == 0
    for out, what in (
        (run / "metrics.csv", f"--out {run / 'metrics.csv'}: is a file, not a folder"),
        (
            run / "metrics.csv" / "r",
            f"--out {run / 'metrics.csv' / 'r'}: {run / 'metrics.csv'} is a",
        ),
    ):
        capsys.readouterr()
        assert cli.main(["report", str(run), "--out", str(out)]) == 2
        if comm.rank == 0:
            assert f"fsi: error: {what}" in capsys.readouterr().err
    # --overwrite: the earlier run's checkpoint is a link to another run's: the link goes.
    other = shared_tmp / "other"
    assert cli.main(["run", CASE, "--out", str(other), *short]) == 0
    if comm.rank == 0:
        import shutil

        shutil.rmtree(run / "checkpoint")
        os.symlink(other / "checkpoint", run / "checkpoint")
    comm.barrier()
    assert cli.main(["run", CASE, "--out", str(run), "--overwrite", *short]) == 0
    assert not (run / "checkpoint").is_symlink() and (other / "checkpoint").is_dir()
    assert (other / "checkpoint" / "checkpoint.json").is_file()
