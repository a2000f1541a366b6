"""``fsi report``: the study's tables and plots from run folders."""

import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import pytest

from fsi import cli, io, report

SHORT = ["structure.mode=rigid", "time.end=0.004", "time.schedule=[{until: 0.004, dt: 0.001}]",
         "output.report_times=[0.002, 0.004]"]


@pytest.fixture(scope="module")
def run_dir():
    """A 4-step rigid run in a folder shared by the ranks (see conftest.shared_tmp)."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    out = path / "rigid"
    assert cli.main(["run", "configs/stenosis_fixed_newtonian.yaml", "--out", str(out),
                     *sum((["--set", s] for s in SHORT), [])]) == 0
    yield out
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def test_tables_hold_the_rows_at_the_report_times(run_dir, capsys):
    run = report.load_run(run_dir)
    rows = io.read_metrics(run_dir / "metrics.csv")
    by_t = {round(r["t"], 9): r for r in rows}
    table = report.peaks_table([run], "peak_velocity", "Peak velocity (m/s)")
    cells = table.splitlines()[2].split("|")[2:-1]
    assert [float(c) for c in cells] == [pytest.approx(by_t[t]["peak_velocity"], rel=1e-3)
                                         for t in (0.002, 0.004)]
    # A time with no step is shown as '–', not interpolated.
    assert report.value_at(rows, 0.0025, "peak_velocity") is None
    assert "| 4 | 0.004 |" in report.effort_table([run])


def test_cli_writes_report_and_plots(run_dir, capsys):
    out = run_dir.parent / f"report{MPI.COMM_WORLD.rank}"
    assert cli.main(["report", str(run_dir), str(run_dir), "--out", str(out)]) == 0
    if MPI.COMM_WORLD.rank == 0:
        text = (out / "report.md").read_text()
        assert "Table 1: Peak velocity" in text and "Table 3: Peak displacement" in text
        assert text == report.markdown([report.load_run(run_dir)] * 2)
        assert (out / "peak_velocity.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert not (out / "max_sss.png").exists()  # a rigid run has no structure stress
        assert "Table 2: Peak pressure" in capsys.readouterr().out


def test_a_folder_that_is_not_a_run_is_refused(shared_tmp, capsys):
    assert cli.main(["report", str(shared_tmp / "nothing")]) == 2
    if MPI.COMM_WORLD.rank == 0:
        assert "no config.yaml (not a folder written by fsi run)" in capsys.readouterr().err
