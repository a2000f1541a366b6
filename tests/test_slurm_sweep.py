"""``fsi sweep --scheduler slurm``: the batch script (everything quoted), bad input refused with
one line, an array task's outcome in the collected table, and a real one-node Slurm
(tests/slurm_cluster.py) running a sweep whose table equals the same sweep run in-process."""

import csv
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

from mpi4py import MPI

import pytest
from slurm_cluster import Cluster, ClusterError

from fsi import cli
from fsi.output import metrics_csv
from fsi.run import slurm

STENOSIS = "configs/stenosis_moving_newtonian.yaml"
CHANNEL = "configs/channel_poiseuille.yaml"
SWEEP_WAIT = 300  # s for a submitted sweep to leave the queue
serial_lane = pytest.mark.skipif(
    MPI.COMM_WORLD.size > 1,
    reason="starts Slurm's daemons and submits jobs that start their own MPI ranks; runs in "
    "the serial lane",
)


def sweep_main(case, *options: str) -> int:
    return cli.main(["sweep", str(case), *map(str, options)])


def rank0(text: str) -> str:
    return MPI.COMM_WORLD.bcast(text, root=0)


def steps(run) -> int:
    """The lines of ``run``'s metrics.csv past its header (0: none yet)."""
    path = run / "metrics.csv"
    return max(len(path.read_text().splitlines()) - 1, 0) if path.is_file() else 0


def read_table(out) -> list[dict[str, str]]:
    with (out / "sweep.csv").open(newline="") as f:
        return list(csv.DictReader(f))


# --------------------------------------------------------------------------------------------
# The script and bad input (no Slurm needed)


def test_the_batch_script_quotes_every_word(shared_tmp, capsys):
    """A dry run writes the script only; a folder and a value with blanks and quotes come out
    as the same words in the task's command, which runs each run as a job array task."""
    out = shared_tmp / "a sweep's folder"
    options = ["--vary", "fluid.rheology.viscosity=0.0035,0.004", "--set", "name=it's a $test"]
    slurm_options = ["--slurm-option", "time=00:10:00", "--slurm-option", "exclusive"]
    assert (
        sweep_main(
            CHANNEL,
            "--out",
            out,
            *options,
            "--scheduler",
            "slurm",
            "-n",
            "--ranks-per-run",
            "2",
            *slurm_options,
        )
        == 0
    )
    assert rank0(capsys.readouterr().out) == ""  # no job id: not submitted
    text = (out / "sweep.sbatch").read_text()
    for line in (
        "#SBATCH --array=1,2",
        "#SBATCH --ntasks=2",
        "#SBATCH --signal=USR1@120",
        "#SBATCH --time=00:10:00",
        "#SBATCH --exclusive",
    ):
        assert line in text.splitlines(), text
    srun = next(line for line in text.splitlines() if line.startswith("srun "))
    words = shlex.split(srun)
    assert words[:3] == ["srun", "-n", "2"] and words[-2:] == ["--task", "$SLURM_ARRAY_TASK_ID"]
    assert words[3:7] == [sys.executable, "-m", "fsi", "sweep"]
    assert words[7:10] == [str(Path(CHANNEL).absolute()), "--out", str(out.absolute())]
    assert "name=it's a $test" in words
    assert (
        "folders=([1]=fluid.rheology.viscosity=0.0035 [2]=fluid.rheology.viscosity=0.004)" in text
    )
    if MPI.COMM_WORLD.rank == 0:
        assert (
            subprocess.run(["bash", "-n", str(out / "sweep.sbatch")], check=False).returncode == 0
        )
    assert (out / "fluid.rheology.viscosity=0.004" / slurm.SUBMITTED).is_file()
    assert not (out / "sweep.csv").exists()


BAD = [
    (["--scheduler", "pbs"], "--scheduler pbs: expected local or slurm"),
    (["--scheduler", "slurm", "--slurm-option", "time=1\n#SBATCH --x"], "--slurm-option"),
    (["--scheduler", "slurm", "--slurm-option", "comment=a;rm -rf /"], "--slurm-option"),
    (["--scheduler", "slurm", "--slurm-option", "comment=$(id)"], "--slurm-option"),
    (["--scheduler", "slurm", "--slurm-option", "array=1-3"], "--slurm-option array: set by"),
    (["--scheduler", "slurm", "--ranks-per-run", "0"], "--ranks-per-run 0: expected a positive"),
    (["--ranks-per-run", "2"], "--ranks-per-run and --slurm-option go with --scheduler slurm"),
]


@pytest.mark.parametrize("options, message", BAD, ids=[m[:30] for _, m in BAD])
def test_bad_slurm_input_exits_2_with_one_line(shared_tmp, capsys, options, message):
    out = shared_tmp / "sweep"
    status = sweep_main(CHANNEL, "--out", out, "--vary", "fluid.density=1000,1060", *options)
    err = rank0(capsys.readouterr().err)
    assert status == 2 and err.startswith(f"fsi: error: {message}"), err
    assert err.count("\n") == 1 and not out.exists()


def test_a_slurm_option_spelled_as_sbatch_spells_it_is_taken(shared_tmp, capsys):
    """``--slurm-option '--time=1'`` (sbatch's own spelling) got argparse's bare "expected one
    argument": it is the option time=1; a value with a blank is still refused naming it."""
    out = shared_tmp / "dashed"
    vary = ["--vary", "fluid.density=1000,1060", "--scheduler", "slurm", "-n"]
    assert sweep_main(CHANNEL, "--out", out, *vary, "--slurm-option", "--time=1") == 0
    assert "#SBATCH --time=1" in (out / "sweep.sbatch").read_text().splitlines()
    capsys.readouterr()
    assert sweep_main(CHANNEL, "--out", out, *vary, "--slurm-option", "--time 1") == 2
    err = rank0(capsys.readouterr().err)
    assert err.startswith("fsi: error: --slurm-option '--time 1': ' ' is not allowed"), err


def test_no_sbatch_exits_2(shared_tmp, capsys, monkeypatch):
    monkeypatch.setenv("PATH", str(shared_tmp))
    out = shared_tmp / "sweep"
    assert (
        sweep_main(
            CHANNEL, "--out", out, "--vary", "fluid.density=1000,1060", "--scheduler", "slurm"
        )
        == 2
    )
    err = rank0(capsys.readouterr().err)
    assert (
        err == "fsi: error: --scheduler slurm: sbatch not found (is Slurm's client on the PATH?)\n"
    )


def test_collect_needs_a_submitted_sweep(shared_tmp, capsys):
    assert sweep_main(shared_tmp, "--collect") == 2
    err = rank0(capsys.readouterr().err)
    assert err.startswith(f"fsi: error: --collect: {shared_tmp} holds no readable sweep.json")
    assert err.count("\n") == 1


def test_a_failed_task_is_recorded_and_collected(shared_tmp, capsys):
    """The array tasks' command run here: task 1 fails (one Newton iteration allowed), task 2
    finishes; the collected table has ``failed: <why>`` and the numbers, exit status 3."""
    out = shared_tmp / "sweep"
    options = ["--out", str(out), "--vary", "fluid.solver.max_iterations=1,25"]
    options += "--set time.end=0.002 --set time.retries=0".split()
    assert sweep_main(CHANNEL, *options, "--scheduler", "slurm", "--dry-run") == 0
    assert sweep_main(CHANNEL, *options, "--task", "1") == 3
    assert sweep_main(CHANNEL, *options, "--task", "2") == 0
    assert sweep_main(CHANNEL, *options, "--task", "3") == 2
    capsys.readouterr()
    assert sweep_main(out, "--collect") == 3
    err = rank0(capsys.readouterr().err)
    first, second = read_table(out)
    assert first["status"].startswith("failed: solve failed: fluid step to t = 0.001 s")
    assert second["status"] == "done" and float(second["peak_inlet_flow_rate"]) > 0
    assert "sweep 1/2: fluid.solver.max_iterations=1: failed: solve failed" in err


def fake(folder: Path, name: str, script: str) -> None:
    """An executable ``folder/name`` (rank 0) running the shell ``script``."""
    if MPI.COMM_WORLD.rank == 0:
        folder.mkdir(exist_ok=True)
        (folder / name).write_text("#!/bin/sh\n" + script)
        (folder / name).chmod(0o755)
    MPI.COMM_WORLD.barrier()


def test_a_missing_or_failing_squeue_is_not_taken_for_an_ended_task(
    shared_tmp, capsys, monkeypatch
):
    """No ``squeue``, or one failing, said nothing of the queued tasks, which ``--collect``
    then marked ``failed: ... ended without an outcome`` (exit 3) and a new submission gave to
    ``sbatch`` again. Now their state is unknown: pending, not submitted again, said why;
    Slurm's own "Invalid job id" (the job ended long ago) still means ended. ``sbatch`` output
    that is not a job id is refused (exit 2), not recorded as a job."""
    bin_ = shared_tmp / "bin"
    calls = shared_tmp / "sbatch.calls"
    fake(bin_, "sbatch", f"echo call >> {calls}\necho 4242\n")
    monkeypatch.setenv("PATH", str(bin_))  # no squeue
    out = shared_tmp / "sweep"
    options = [CHANNEL, "--out", out, "--vary", "fluid.density=1000,1060"]
    assert sweep_main(*options, "--scheduler", "slurm") == 0
    capsys.readouterr()
    assert sweep_main(out, "--collect") == 0
    err = rank0(capsys.readouterr().err)
    assert "failed" not in err, err
    assert "pending: unknown, the state of its array task 4242_1 cannot be read (squeue not " in err
    assert [row["status"].split(",")[0] for row in read_table(out)] == ["pending: unknown"] * 2
    assert sweep_main(*options, "--scheduler", "slurm") == 0  # not submitted again
    err = rank0(capsys.readouterr().err)
    assert "2 runs submitted earlier not submitted again: squeue cannot tell" in err
    assert rank0(calls.read_text() if MPI.COMM_WORLD.rank == 0 else "") == "call\n"
    fake(bin_, "squeue", "echo 'slurm_load_jobs error: Unable to contact slurm controller' >&2\n"
         "exit 1\n")  # fmt: skip
    assert sweep_main(out, "--collect") == 0
    assert "(squeue failed: slurm_load_jobs error: Unable to contact" in rank0(
        capsys.readouterr().err
    )
    fake(bin_, "squeue", "echo 'slurm_load_jobs error: Invalid job id specified' >&2\nexit 1\n")
    assert sweep_main(out, "--collect") == 3  # Slurm no longer knows the job: it ended
    assert "failed: its array task 4242_1 ended without an outcome" in rank0(
        capsys.readouterr().err
    )
    fake(bin_, "sbatch", "echo 'weird output'\n")
    other = shared_tmp / "other"
    assert sweep_main(CHANNEL, "--out", other, "--vary", "fluid.density=1000,1060",
                      "--scheduler", "slurm") == 2  # fmt: skip
    err = rank0(capsys.readouterr().err)
    assert "fsi: error: sbatch printed 'weird output', not a job id: " in err, err
    assert json.loads((other / "sweep.json").read_text())["jobs"] == {}  # no job recorded


# --------------------------------------------------------------------------------------------
# A real Slurm


@pytest.fixture(scope="module")
def cluster():
    """A one-node Slurm (tests/slurm_cluster.py) for this module's tests, stopped after."""
    if os.geteuid() != 0:
        pytest.skip("Slurm's daemons run the jobs as their users: starting them needs root")
    started = Cluster()
    try:
        started.start()
    except ClusterError as e:
        started.stop()
        pytest.fail(str(e))
    os.environ["SLURM_CONF"] = started.env["SLURM_CONF"]
    yield started
    del os.environ["SLURM_CONF"]
    started.stop()


@serial_lane
def test_a_slurm_sweep_tables_the_numbers_of_the_same_sweep_run_here(cluster, shared_tmp, capsys):
    """Two coarse two-step stenosis runs, submitted with 1 and with 2 ranks per run: once the
    jobs have left the queue, each collected table equals the in-process sweep's to 1e-9."""
    options = ["--vary", "geometry.stenosis_degree=0.4,0.5", "--set", "time.end=0.0005"]
    jobs = {}
    for ranks in (1, 2):
        out = shared_tmp / f"slurm{ranks}"
        assert (
            sweep_main(
                STENOSIS,
                "--out",
                out,
                *options,
                "--scheduler",
                "slurm",
                "--ranks-per-run",
                str(ranks),
            )
            == 0
        )
        jobs[out] = capsys.readouterr().out.strip()
        assert jobs[out].isdigit()
    assert sweep_main(STENOSIS, "--out", shared_tmp / "here", *options) == 0
    here = read_table(shared_tmp / "here")
    for out, job in jobs.items():
        assert cluster.wait(job, SWEEP_WAIT), f"job {job} still queued after {SWEEP_WAIT} s"
        logs = "\n".join(p.read_text() for p in sorted((out / slurm.TASKS).glob("*.log")))
        assert sweep_main(out, "--collect") == 0, logs
        table = read_table(out)
        assert [r["status"] for r in table] == ["done", "done"], logs
        for row, expected in zip(table, here, strict=True):
            for name, value in expected.items():
                if name != "status" and value:
                    assert float(row[name]) == pytest.approx(float(value), rel=1e-9), name
                else:
                    assert row[name] == value, name
    ranks = (shared_tmp / "slurm2" / "geometry.stenosis_degree=0.4" / "summary.json").read_text()
    assert '"ranks": 2' in ranks


@serial_lane
def test_a_task_signalled_before_its_time_limit_stops_and_a_resubmission_continues_it(
    cluster, shared_tmp, capsys
):
    """SIGUSR1 to the job's ranks (what ``--signal=USR1@120`` sends before the time limit):
    the run stops with a checkpoint, the table says ``stopped``; the same command submitted
    again (with a nearer end) continues it from its checkpoint to the end."""
    out = shared_tmp / "sweep"
    first = out / "fluid.rheology.viscosity=0.0035"
    options = [
        "--out",
        str(out),
        "--vary",
        "fluid.rheology.viscosity=0.0035",
        "--set",
        "time.schedule=[{until: 10, dt: 0.001}]",
        "--scheduler",
        "slurm",
    ]
    assert sweep_main(CHANNEL, *options, "--set", "time.end=10") == 0
    job = capsys.readouterr().out.strip()
    deadline = time.monotonic() + SWEEP_WAIT
    while time.monotonic() < deadline and steps(first) < 2:
        time.sleep(0.5)
    assert cluster.run("scancel", "--signal=USR1", job).returncode == 0
    assert cluster.wait(job, SWEEP_WAIT)
    assert sweep_main(out, "--collect") == 0
    assert [r["status"] for r in read_table(out)] == ["stopped"]
    last = int(max(r["step"] for r in metrics_csv.read_metrics(first / "metrics.csv")))

    end = f"time.end={round((last + 2) * 0.001, 6)}"
    assert sweep_main(CHANNEL, *options, "--set", end) == 0
    job = capsys.readouterr().out.strip()
    assert cluster.wait(job, SWEEP_WAIT)
    assert sweep_main(out, "--collect") == 0
    assert [r["status"] for r in read_table(out)] == ["done"]
    assert [r["step"] for r in metrics_csv.read_metrics(first / "metrics.csv")] == list(
        range(1, last + 3)
    )
    log = next((out / slurm.TASKS).glob(f"{job}_1.log")).read_text()
    assert f"resumed from its checkpoint at t = {last * 0.001:.6g} s" in log
