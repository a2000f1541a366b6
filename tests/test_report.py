"""``fsi report``: the study's tables and plots from run folders."""

import csv
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
    assert "inlet_flow_rate" not in report.load_run(old).rows[0]
    out = run_dir.parent / f"old_report{comm.rank}"
    assert cli.main(["report", str(old), str(run_dir), "--out", str(out)]) == 0
    assert report.flow_rate_plot([report.load_run(old)], out / "none.png") is False
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
    assert [r["step"] for r in report.load_run(cut).rows] == [1, 2, 3]
    assert cli.main(["report", str(cut), "--times", "0.002", "0.004"]) == 0
    if comm.rank == 0:
        out = capsys.readouterr().out
        row = next(line for line in out.splitlines() if line.startswith("| cut (")
                   and "| 3 |" in line)  # the solver effort: 3 steps
        assert "| 0.003 |" in row
        assert f"{cut / 'metrics.csv'}: line 5 is cut short" in fsi_log.text


@pytest.mark.parametrize("change, expected", [
    (set_cell(3, "peak_velocity", b"1.2.3"), "line 3: peak_velocity: '1.2.3' is not a finite "
     "number"),
    (set_cell(4, "peak_pressure", b"nan"), "line 4: peak_pressure: 'nan' is not a finite number"),
    (set_cell(3, "step", b"2.5"), "line 3: step: '2.5' is not a step number (1, 2, ...)"),
    (set_cell(3, "t", b""), "line 3: t: empty"),
    (set_cell(2, "dt", b"0.001,7"), "line 2: "),  # one cell too many
    (set_cell(4, "max_wss", b"\xff\xfe"), "line 4: not UTF-8 text"),
    (lambda lines: lines[:2] + [lines[2][:12] + b"\r\n"] + lines[3:], "line 3: "),
    (lambda lines: [lines[0].replace(b"step,", b"steps,")] + lines[1:],
     "line 1: no 'step' column (not a metrics table)"),
])
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
