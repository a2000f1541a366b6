"""``metrics.csv`` written and read back: the table a run appends one row per step to, flushed
at every row and kept across restarts (:class:`MetricsTable`; values to 10 significant digits),
and its complete rows read back as text and numbers (:func:`read_rows`, :func:`read_metrics`;
a damaged table raises :class:`MetricsError` naming the file and the line). The other files of
a run: fsi/output/io.py.
"""

from __future__ import annotations

import csv
import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

from mpi4py import MPI

log = logging.getLogger("fsi")


class MetricsError(ValueError):
    """A damaged ``metrics.csv``: the message names the file and the line."""


@dataclass(frozen=True)
class MetricsRow:
    """A complete row of ``metrics.csv``: its line number, its non-empty cells as written and
    their values."""

    line: int
    text: dict[str, str]
    values: dict[str, float]

    @property
    def step(self) -> int:
        return int(self.values["step"])


REQUIRED_COLUMNS = ("step", "t")


def read_rows(path: Path, until_step: int | None = None) -> list[MetricsRow]:
    """The complete rows of the metrics table ``path`` in file order, up to (without) the first
    row of a step after ``until_step`` (default: every row); OSError if it cannot be read.

    Guaranteed for each row: a cell per column of the header, which has ``step`` and ``t``;
    every non-empty cell a finite number; ``step`` a whole number ≥ 1; ``t`` not empty. The
    last line without its line end is a row cut short (a run stopped, or is running, while
    writing it): left out with a warning. Any other line that breaks these rules raises
    :class:`MetricsError` ``"<path>: line <n>: <what>"``. An empty file, or one whose header
    is cut short, has no rows."""
    data = Path(path).read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise MetricsError(f"{path}: line {line}: not UTF-8 text") from None
    lines = text.split("\n")
    cut = lines.pop()  # "" when the file ends with a line end
    if not lines:
        _leave_out_cut(path, cut, len(lines) + 1)
        return []
    header = _header(path, lines[0])
    rows = []
    for number, line in enumerate(lines[1:], start=2):
        row = _metrics_row(path, number, line, header)
        if row is None:  # a blank line
            continue
        if until_step is not None and row.values["step"] > until_step:
            break
        rows.append(row)
    else:
        _leave_out_cut(path, cut, len(lines) + 1)
    return rows


def _leave_out_cut(path: Path, cut: str, number: int) -> None:
    """Warn that line ``number``, ``cut`` (the text after the last line end), is left out; no
    warning when ``cut`` is empty."""
    if cut:
        log.warning(
            "%s: line %d is cut short (a run stopped while writing it): left out",
            path,
            number,
        )


def _header(path: Path, line: str) -> list[str]:
    """The column names of the header line of the metrics table ``path``: each named once,
    ``step`` and ``t`` among them, else :class:`MetricsError`."""
    header = _cells(path, 1, line)
    for name in REQUIRED_COLUMNS:
        if name not in header:
            raise MetricsError(f"{path}: line 1: no {name!r} column (not a metrics table)")
    for name in header:
        if not name or header.count(name) > 1:
            what = f"column {name!r} twice" if name else "a column without a name"
            raise MetricsError(f"{path}: line 1: {what} (not a metrics table)")
    return header


def _metrics_row(path: Path, number: int, line: str, header: list[str]) -> MetricsRow | None:
    """Line ``number`` of the metrics table ``path`` as a row (None if blank): a cell per
    column, ``step`` and ``t`` not empty, finite numbers, ``step`` a whole number ≥ 1, else
    :class:`MetricsError`."""
    cells = _cells(path, number, line)
    if not cells:
        return None
    if len(cells) != len(header):
        raise MetricsError(
            f"{path}: line {number}: {len(cells)} cells, the header has {len(header)} columns"
        )
    text = {k: v for k, v in zip(header, cells) if v != ""}
    for name in REQUIRED_COLUMNS:
        if name not in text:
            raise MetricsError(f"{path}: line {number}: {name}: empty")
    values = {name: _finite_cell(path, number, name, cell) for name, cell in text.items()}
    step = values["step"]
    if step < 1 or step != int(step):
        raise MetricsError(
            f"{path}: line {number}: step: {text['step']!r} is not a step number (1, 2, ...)"
        )
    return MetricsRow(number, text, values)


def _cells(path: Path, number: int, line: str) -> list[str]:
    try:
        return next(csv.reader([line.removesuffix("\r")]), [])
    except csv.Error as e:
        raise MetricsError(f"{path}: line {number}: {e}") from None


def _finite_cell(path: Path, number: int, name: str, cell: str) -> float:
    try:
        value = float(cell)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise MetricsError(f"{path}: line {number}: {name}: {cell[:40]!r} is not a finite number")
    return value


def read_metrics(path: Path) -> list[dict[str, float]]:
    """The complete rows of a ``metrics.csv`` as numbers (:func:`read_rows`: a row cut short
    at the end is left out, a damaged table raises :class:`MetricsError`)."""
    return [row.values for row in read_rows(path)]


class MetricsTable:
    """``metrics.csv``: one row per time step, written by rank 0 and flushed at every row, so a
    run that stops keeps every finished step. On restart the rows up to ``keep_until_step`` of
    ``source`` (default: ``path`` itself) are kept as written (:func:`read_rows`: a row cut
    short at the end, or any after that step, is dropped), and new rows are appended;
    :attr:`kept` holds the kept rows as numbers (on every rank). The table with the kept rows
    replaces ``path`` only once it is complete on disk, so a run stopped meanwhile loses none.
    Collective; a failure to read ``source`` (OSError, :class:`MetricsError`) is raised on
    every rank, one to write ``path`` on rank 0 (after the last collective)."""

    def __init__(
        self,
        comm: MPI.Comm,
        path: Path,
        columns: list[str],
        keep_until_step: int | None = None,
        source: Path | None = None,
    ):
        self.comm, self.path, self.columns = comm, path, list(columns)
        self._file = None
        source = path if source is None else source
        rows: list[MetricsRow] = []
        error = None
        if comm.rank == 0 and keep_until_step is not None and source.exists():
            try:
                rows = read_rows(source, until_step=keep_until_step)
            except (OSError, MetricsError) as e:
                error = e
        kept, error = comm.bcast(
            ([{k: _parse(v) for k, v in r.text.items()} for r in rows], error), root=0
        )
        if error is not None:
            raise error
        self.kept: list[dict] = kept
        if comm.rank == 0:
            self._start(rows)

    def _start(self, rows: list[MetricsRow]) -> None:
        """Write the header and ``rows`` into ``<path>.partial``, then rename it to ``path``
        and keep it open for the new rows."""
        partial = self.path.with_name(self.path.name + ".partial")
        f = partial.open("w", newline="")
        try:
            writer = csv.DictWriter(f, fieldnames=self.columns, extrasaction="raise")
            writer.writeheader()
            for row in rows:
                writer.writerow({k: row.text.get(k, "") for k in self.columns})
            f.flush()
            os.fsync(f.fileno())
            os.replace(partial, self.path)
        except BaseException:
            f.close()
            raise
        self._file, self._writer = f, writer

    def write(self, row: dict) -> None:
        if self._file is not None:
            self._writer.writerow({k: format_value(row.get(k, "")) for k in self.columns})
            self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


def format_value(value) -> str:
    """A metrics value as text: a float to 10 significant digits, −0 as 0 (a flow rate of no
    flow is −∫ 0: "-0" reads as a sign that means nothing)."""
    return f"{value + 0.0:.10g}" if isinstance(value, float) else str(value)


def _parse(text: str) -> int | float | str:
    """A metrics value as written by :func:`format_value`: int, float, or the text itself."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text
