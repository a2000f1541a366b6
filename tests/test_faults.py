"""Faults of a run that are not the solvers' (docs/reliability.md): an --out that cannot take the
run, a disk that fills, a file write that fails on rank 0 alone, a stop signal, an inlet formula
that fails mid-run. Each ends every rank with one message and a documented exit status, and
keeps the last checkpoint that could be written; none hangs (the tests that launch their own
mpirun are bounded by a timeout)."""

import dataclasses
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from mpi4py import MPI

import pytest

from fsi import cli, config
from fsi.output import io, metrics_csv
from fsi.run import errors, simulation

ROOT = Path(__file__).resolve().parents[1]
CHANNEL = str(ROOT / "configs/channel_poiseuille.yaml")
SHORT = ["time.end=0.004"]  # 4 steps of 1 ms, about a second
MPIRUN_ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
}
serial_lane = pytest.mark.skipif(
    MPI.COMM_WORLD.size > 1, reason="launches its own processes; runs in the serial lane"
)


def fsi_run(out: Path, overrides=(), *extra: str) -> int:
    args = ["run", CHANNEL, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
    return cli.main([*args, *extra])


def metrics_steps(out: Path) -> list[int]:
    return [int(row["step"]) for row in metrics_csv.read_metrics(out / "metrics.csv")]


def checkpoint_step(out: Path) -> int:
    return json.loads((out / "checkpoint" / "checkpoint.json").read_text())["step"]


def fsi_command(out: Path, *overrides: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "fsi",
        "run",
        CHANNEL,
        "--out",
        str(out),
        *sum((["--set", s] for s in overrides), []),
    ]


# --------------------------------------------------------------------------------------------
# --out


def test_an_out_holding_a_run_is_refused_unless_overwrite(shared_tmp, capsys):
    out = shared_tmp / "run"
    assert fsi_run(out, SHORT) == 0
    comm = MPI.COMM_WORLD
    if comm.rank == 0:  # an earlier restart's field segment and the user's own notes
        (out / "fields.restart9.xdmf").write_text("stale")
        (out / "notes.txt").write_text("mine")
    comm.barrier()
    capsys.readouterr()
    assert fsi_run(out, ["time.end=0.002"]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    if comm.rank == 0:
        assert "--out" in err and "--overwrite" in err and "--restart" in err
    assert "Traceback" not in err
    assert metrics_steps(out) == [1, 2, 3, 4]  # untouched

    assert fsi_run(out, ["time.end=0.002"], "--overwrite") == 0
    assert metrics_steps(out) == [1, 2]
    assert not (out / "fields.restart9.xdmf").exists()
    assert (out / "notes.txt").read_text() == "mine"


def test_an_out_naming_a_file_is_refused_before_any_computation(shared_tmp, capsys):
    comm = MPI.COMM_WORLD
    taken = shared_tmp / "taken"
    if comm.rank == 0:
        taken.write_text("a file")
    comm.barrier()
    for out in (taken, taken / "below"):
        assert fsi_run(out, SHORT) == cli.EXIT_USAGE
        err = capsys.readouterr().err
        if comm.rank == 0:
            assert f"--out: {taken} is a file, not a folder" in err
        assert "Traceback" not in err
    assert taken.read_text() == "a file"


def mounted_tmpfs(folder: Path, options: str, why: str):
    """A tmpfs mounted at ``folder`` (by rank 0) for the test's duration, or a skip saying
    ``why`` it is needed where the machine does not let the tests mount one."""
    comm = MPI.COMM_WORLD
    mounted = False
    if comm.rank == 0:
        folder.mkdir()
        mounted = (
            subprocess.run(
                ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)], capture_output=True
            ).returncode
            == 0
        )
    if not comm.bcast(mounted, root=0):
        pytest.skip(f"this machine does not let the tests mount a tmpfs ({why})")
    yield folder
    comm.barrier()
    if comm.rank == 0:
        subprocess.run(["umount", str(folder)], check=True)


@pytest.fixture
def read_only_folder(shared_tmp):
    """A read-only mount (root ignores permission bits, not a read-only file system)."""
    yield from mounted_tmpfs(shared_tmp / "read-only", "ro,size=64k", "read-only --out")


def test_a_read_only_out_is_refused_before_any_computation(read_only_folder, capsys):
    assert fsi_run(read_only_folder / "run", SHORT) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert f"--out: {read_only_folder}: cannot write there" in err
    assert "Traceback" not in err


@serial_lane
def test_a_read_only_out_ends_both_ranks_of_mpirun(read_only_folder):
    """The defect of issue #14: rank 0 failed to make the folder, rank 1 waited for ever."""
    command = [
        "mpirun",
        "-n",
        "2",
        "--oversubscribe",
        *fsi_command(read_only_folder / "run", *SHORT),
    ]
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=120, env={**os.environ, **MPIRUN_ENV}
    )
    assert result.returncode == cli.EXIT_USAGE, result.stderr
    assert result.stderr.count("fsi: error: --out:") == 1


# --------------------------------------------------------------------------------------------
# Writes that fail mid-run


def test_a_write_failing_on_rank_0_alone_ends_every_rank(shared_tmp, monkeypatch, capsys):
    """metrics.csv is written by rank 0 alone: its failure (here a simulated full disk at step
    3) must reach the other ranks, which would otherwise wait in step 4's collectives."""
    write = metrics_csv.MetricsTable.write

    def full_at_step_3(self, row):
        if row["step"] == 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.path))
        write(self, row)

    monkeypatch.setattr(metrics_csv.MetricsTable, "write", full_at_step_3)
    out = shared_tmp / "run"
    assert fsi_run(out, [*SHORT, "output.checkpoint_every=2"]) == cli.EXIT_OUTPUT_FAILED
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert f"cannot write the run's files: {out / 'metrics.csv'}: No space left" in err
        assert "step 2 (t = 0.002 s) is checkpointed" in err
    assert "Traceback" not in err
    assert metrics_steps(out) == [1, 2]
    assert checkpoint_step(out) == 2
    assert not (out / "checkpoint.partial").exists()
    log = (out / "run.log").read_text()  # the progress and the reason, with the restart command
    assert "step 2/4" in log and "No space left" in log and f"--restart {out}" in log


def test_a_checkpoint_that_cannot_be_written_keeps_the_previous_one(
    shared_tmp, monkeypatch, capsys
):
    """A full disk while checkpointing: the partial copy is removed, the previous checkpoint
    stays, the run goes on; when the last step cannot be checkpointed the run fails (exit 4)
    naming the checkpoint that is left."""
    from fsi.run import checkpoint

    write = checkpoint._write_swap

    def full_after_step_2(out, comm, arrays, meta):
        if meta["step"] > 2:  # a partial copy, as a real write leaves it (once, before the
            if comm.rank == 0:  # clean-up: a rank made late could make it after the clean-up)
                (out / checkpoint.PARTIAL).mkdir(exist_ok=True)
            comm.barrier()
            raise checkpoint.CheckpointError(f"{out}: [Errno 28] No space left on device")
        write(out, comm, arrays, meta)

    monkeypatch.setattr(checkpoint, "_write_swap", full_after_step_2)
    out = shared_tmp / "run"
    assert fsi_run(out, [*SHORT, "output.checkpoint_every=1"]) == cli.EXIT_OUTPUT_FAILED
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert "no checkpoint of step 3" in err and "no checkpoint of the last step 4" in err
        assert "step 2 (t = 0.002 s) is checkpointed" in err
    assert metrics_steps(out) == [1, 2, 3, 4]
    assert checkpoint_step(out) == 2
    assert not (out / checkpoint.PARTIAL).exists()


@pytest.fixture
def small_disk(shared_tmp):
    """A 1.2 MB tmpfs: the channel's fields and two checkpoints do not fit."""
    yield from mounted_tmpfs(
        shared_tmp / "small-disk",
        "size=1200k",
        "the simulated full disks of the tests above still run",
    )


@pytest.mark.parametrize("ranks", [1, 2])
@serial_lane
def test_a_disk_that_fills_up_ends_the_run_with_its_last_checkpoint(small_disk, ranks):
    out = small_disk / "run"
    command = fsi_command(out, "time.end=0.05", "output.checkpoint_every=5")
    if ranks > 1:
        command = ["mpirun", "-n", str(ranks), "--oversubscribe", *command]
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=180, env={**os.environ, **MPIRUN_ENV}
    )
    assert result.returncode == cli.EXIT_OUTPUT_FAILED, result.stderr[-3000:]
    assert "(the disk is full)" in result.stderr
    assert "Traceback" not in result.stderr
    step = checkpoint_step(out)
    assert step % 5 == 0 and step >= 5
    assert f"step {step} (t = {step / 1000:g} s) is checkpointed" in result.stderr
    assert not (out / "checkpoint.partial").exists()
    assert max(metrics_steps(out)) >= step


# --------------------------------------------------------------------------------------------
# Stop signals


def start_and_signal(command: list[str], sig: int, env: dict | None = None):
    """Start ``command``, send ``sig`` once it reports step 5, return (status, stderr)."""
    process = subprocess.Popen(
        command, stderr=subprocess.PIPE, text=True, env={**os.environ, **(env or {})}
    )
    lines = []
    deadline = time.monotonic() + 120
    for line in process.stderr:
        lines.append(line)
        if line.startswith("step 5/"):
            process.send_signal(sig)
            break
        assert time.monotonic() < deadline, "".join(lines)
    try:
        lines.extend(process.stderr)
        status = process.wait(timeout=120)
    finally:
        process.kill()
    return status, "".join(lines)


LONG = [
    "time.end=10",
    "time.schedule=[{until: 10, dt: 0.001}]",
    "output.checkpoint_every=1000",
    "output.fields_every=1000",
]


@serial_lane
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_checkpoints_the_last_step_and_says_how_to_continue(shared_tmp, sig):
    out = shared_tmp / "run"
    status, err = start_and_signal(fsi_command(out, *LONG), sig)
    assert status == 128 + sig, err
    assert "Traceback" not in err
    last = max(metrics_steps(out))
    assert last >= 5 and checkpoint_step(out) == last
    assert f"--restart {out}" in err and "--set time.end=10" in err

    # ... and the run goes on from there: the restart command of the message, shortened.
    assert fsi_run(out, ["time.end=0.012", *LONG[1:]], "--restart", str(out)) == 0
    assert metrics_steps(out) == list(range(1, 13))


@serial_lane
@pytest.mark.parametrize("delay", [0.2, 1.0, 2.0, 4.0])
def test_sigterm_stops_a_run_in_bounded_time_in_any_phase(shared_tmp, delay):
    """SIGTERM ``delay`` seconds after ``fsi run`` starts, wherever the run then is (measured on
    the fine channel here: 0.2 s in Python's imports, where the default action ends it at once;
    1 and 2 s in the set-up, the mesh and the forms; 4 s in the time loop): the run ends within
    60 s of it (measured ≤ 1.3 s), with 143 (or killed by the signal, before fsi's handler is
    in place), no traceback, and after any step the last one checkpointed. Every step is
    bounded (a period shorter than a step is refused, issue #49): so is the wait."""
    out = shared_tmp / "run"
    process = subprocess.Popen(
        fsi_command(out, *LONG, "mesh.level=fine"), stderr=subprocess.PIPE, text=True
    )
    time.sleep(delay)
    process.send_signal(signal.SIGTERM)
    start = time.monotonic()
    try:
        _, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert time.monotonic() - start < 60
    assert process.returncode in (128 + signal.SIGTERM, -signal.SIGTERM), err
    assert "Traceback" not in err
    steps = metrics_steps(out) if (out / "metrics.csv").exists() else []
    if steps:
        assert process.returncode == 128 + signal.SIGTERM
        assert checkpoint_step(out) == max(steps)


@serial_lane
def test_sigusr1_stops_an_mpirun_run_after_the_step_with_a_checkpoint(shared_tmp):
    """mpirun kills its ranks within a second of SIGINT or SIGTERM, but forwards SIGUSR1."""
    out = shared_tmp / "run"
    status, err = start_and_signal(
        ["mpirun", "-n", "2", "--oversubscribe", *fsi_command(out, *LONG)],
        signal.SIGUSR1,
        MPIRUN_ENV,
    )
    assert status == 128 + signal.SIGUSR1, err
    last = max(metrics_steps(out))
    assert last >= 5 and checkpoint_step(out) == last
    assert err.count("fsi: stopped by signal") == 1


# --------------------------------------------------------------------------------------------
# An inlet formula that fails at run time


def test_an_inlet_formula_failing_mid_run_fails_the_step_with_a_checkpoint(shared_tmp):
    """The configuration check evaluates the formula at the schedule's times; a time it cannot
    see (here a case built without that check) fails the step like a solver (exit 3) and the
    last converged step is checkpointed."""
    case = config.load(CHANNEL, [*SHORT, "output.checkpoint_every=1"])
    inlet = config.InletPressure(formula="1/(t - 0.003) * 0 + 1")
    case = dataclasses.replace(case, fluid=dataclasses.replace(case.fluid, inlet=inlet))
    out = shared_tmp / "run"
    with pytest.raises(errors.StepFailed, match=r"step 3 .*fluid\.inlet: .*t = 0\.003") as failed:
        simulation.run(case, out, MPI.COMM_WORLD)
    assert (failed.value.step, failed.value.checkpoint) == (2, out / "checkpoint")
    assert metrics_steps(out) == [1, 2]
    assert checkpoint_step(out) == 2


def test_a_mesh_build_leaves_the_runs_sigint_handler_in_place():
    """gmsh's Python API sets SIGINT to its default while it runs (and 4.13 does not restore
    it): the build asks it not to, so Ctrl-C still reaches the run's checkpointing handler."""
    from fsi.physics import mesh

    def handler(signum, frame):
        pass

    previous = signal.signal(signal.SIGINT, handler)
    try:
        mesh.build(config.load(CHANNEL), MPI.COMM_WORLD)
        assert signal.getsignal(signal.SIGINT) is handler
    finally:
        signal.signal(signal.SIGINT, previous)


@serial_lane
def test_kill_9_keeps_the_field_files_readable_and_a_restart_says_what_they_hold(
    shared_tmp, capsys
):
    """A run killed with SIGKILL (no handler runs) after step 8, fields written every 2
    steps: fields.xdmf/.h5 hold every snapshot written before the kill (the file is closed
    after each), ``fsi plot`` draws one, and a restart from the checkpoint says what the
    earlier file holds."""
    out = shared_tmp / "killed"
    every = ["output.fields_every=2", "output.checkpoint_every=4"]
    process = subprocess.Popen(
        fsi_command(out, *LONG[:2], *every), stderr=subprocess.PIPE, text=True
    )
    lines, deadline = [], time.monotonic() + 120
    try:
        for line in process.stderr:
            lines.append(line)
            if line.startswith("step 8/"):
                process.send_signal(signal.SIGKILL)
                break
            assert time.monotonic() < deadline, "".join(lines)
        assert process.wait(timeout=60) == -signal.SIGKILL
    finally:
        process.kill()
    times = io.snapshot_times(out / "fields.xdmf")
    assert len(times) >= 4 and times[0] == 0.0, times  # t = 0, 2, 4, 6 ms at least
    picture = shared_tmp / "v.png"
    drawn = ["--field", "velocity", "--time", str(times[-1]), "--out", str(picture)]
    assert cli.main(["plot", str(out), *drawn]) == 0
    damaged = shared_tmp / "damaged"
    shutil.copytree(out, damaged)
    h5 = damaged / "fields.h5"
    h5.write_bytes(h5.read_bytes()[:2000])  # as a run killed while writing it left it
    capsys.readouterr()
    assert fsi_run(out, ["time.end=0.01", LONG[1], *every], "--restart", str(out)) == 0
    err = capsys.readouterr().err
    assert f"fields.xdmf: {len(times)} snapshots kept, the last at t = {times[-1]:g} s" in err
    assert fsi_run(damaged, ["time.end=0.01", LONG[1], *every], "--restart", str(damaged)) == 0
    err = capsys.readouterr().err
    assert f"fsi: warning: {h5} cannot be read (OSError): its snapshots are lost" in err
