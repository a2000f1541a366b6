"""The files of one ``fsi run`` in its ``--out`` folder, owned by one object,
:class:`RunOutputs`: ``config.yaml``, ``run.log``, ``metrics.csv``, the field files (a segment
per restart) and, at the end, ``summary.json`` with its per-heartbeat table
(:func:`cycle_table`). The formats are fsi/output/io.py's; the checkpoint and the files derived
from it (``wall_indices.csv``) are written apart, by the loop's checkpoints
(fsi/run/simulation.py).
"""

from __future__ import annotations

import logging
import math
import time as wallclock
from pathlib import Path

from mpi4py import MPI

from fsi import config
from fsi.numerics.timestepping import SAME_TIME, Step
from fsi.output import io, metrics_csv, provenance
from fsi.output.columns import heartbeat
from fsi.run import checkpoint
from fsi.run.errors import OutputFailed
from fsi.run.steppers import Stepper

log = logging.getLogger("fsi")


class RunOutputs:
    """The files of a run of ``stepper`` in ``out``, opened at once: the folder is made and an
    earlier run's files (:data:`fsi.output.io.RUN_FILES`) are deleted or, when ``restart``
    continues the run in ``out``, only the field segments after its step; ``config.yaml`` (the
    resolved ``case``) is written, ``run.log`` started (rank 0's log until :meth:`close`),
    ``metrics.csv`` started with the rows up to the restart's step (:attr:`rows`; a ``cycle``
    column with a periodic inlet), and a field file per ``stepper.field_files()`` entry (a new
    segment after a restart, :func:`fsi.output.io.field_segment`) stores its reference mesh
    (so load a restart's state, which may move the fluid mesh, afterwards).

    Then :meth:`write_step` per step and :meth:`write_summary` at the end. Every write is agreed by
    all ranks (:func:`fsi.output.io.collectively`): a failure to open raises :class:`OutputFailed`,
    one to write :class:`fsi.output.io.OutputError`, on every rank. A context manager. Collective.
    """

    def __init__(
        self,
        case: config.Case,
        out: Path,
        comm: MPI.Comm,
        stepper: Stepper,
        restart: checkpoint.Checkpoint | None,
    ):
        self.case, self.out, self.comm = case, out, comm
        self.stepper, self.restart = stepper, restart
        self.period = config.heartbeat_period(case)
        self._log: logging.Handler | None = None
        self.table: metrics_csv.MetricsTable | None = None
        self.writers: list[tuple[io.FieldWriter, list]] = []
        try:
            self._open()
        except io.OutputError as e:
            self.close()
            raise OutputFailed(str(e)) from e
        self.rows: list[dict] = list(self.table.kept)
        """Every row of metrics.csv: those kept from before a restart and this run's."""

    def _open(self) -> None:
        """Make the folder and open the files, in the order the class docstring says."""
        comm, out, restart = self.comm, self.out, self.restart
        first = None if restart is None else restart.step
        continuing = restart is not None and restart.continues(out)
        columns = list(self.stepper.columns)
        if self.period > 0:
            columns.insert(columns.index("dt") + 1, "cycle")
        config_yaml = config.to_yaml(self.case)
        field_files = self.stepper.field_files()

        def prepare() -> None:
            out.mkdir(parents=True, exist_ok=True)
            if continuing:
                io.remove_later_segments(out, list(field_files), first)
            else:
                io.remove_run_files(out)
            (out / "config.yaml").write_text(config_yaml)

        io.on_rank0(comm, prepare, out)
        run_log = out / "run.log"
        self._log = io.collectively(
            comm, lambda: io.start_log(run_log) if comm.rank == 0 else None, run_log
        )
        metrics = out / "metrics.csv"
        source = None if restart is None or continuing else restart.run_dir / "metrics.csv"
        self.table = io.collectively(
            comm,
            lambda: metrics_csv.MetricsTable(
                comm, metrics, columns, keep_until_step=first, source=source
            ),
            metrics,
        )
        if continuing and comm.rank == 0:
            self._report_earlier_fields(list(field_files), first)
        for name, (mesh, fields) in field_files.items():
            path = out / io.field_segment(name, first)
            writer = io.collectively(
                comm, lambda path=path, mesh=mesh: io.FieldWriter(comm, path, mesh), path
            )
            self.writers.append((writer, fields))

    def _report_earlier_fields(self, names: list[str], first: int) -> None:
        """Say what the field files of the segments this restart continues hold: their
        snapshots, or that one cannot be read (a run killed while writing it, before field
        files were closed after every snapshot). Rank 0."""
        for name in names:
            stem = Path(name).stem
            for xdmf in sorted(self.out.glob(f"{stem}*.xdmf")):
                try:
                    times = io.snapshot_times(xdmf)
                except (OSError, KeyError, IndexError, ValueError) as e:
                    log.warning(
                        "fsi: warning: %s cannot be read (%s): its snapshots are lost; this "
                        "restart writes its own to %s",
                        xdmf.with_suffix(".h5"),
                        type(e).__name__,
                        io.field_segment(name, first),
                    )
                    continue
                last = f", the last at t = {times[-1]:.6g} s" if times else ""
                log.info("%s: %d snapshots kept%s", xdmf.name, len(times), last)

    def __enter__(self) -> RunOutputs:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def write_step(self, row: dict, final: bool) -> None:
        """A step's metrics row (its heartbeat added as ``cycle`` with a periodic inlet;
        flushed at once), and the fields every ``output.fields_every`` steps and when the step
        is the ``final`` one."""
        if self.period > 0:
            row = {**row, "cycle": heartbeat(row["t"], self.period)}
        self.write_row(row)
        self.rows.append(row)
        if row["step"] % self.case.output.fields_every == 0 or final:
            self.write_fields(row["t"])

    def write_row(self, row: dict) -> None:
        io.on_rank0(self.comm, lambda: self.table.write(row), self.table.path)

    def write_fields(self, t: float) -> None:
        for writer, fields in self.writers:
            io.collectively(self.comm, lambda w=writer, f=fields: w.write(t, f), writer.path)

    def write_summary(
        self,
        retried: list[Step],
        saved: tuple[Path, int, float] | None,
        start: float,
        rejected: list[Step] | None = None,
    ) -> dict:
        """Write ``summary.json`` and return it: totals and means over every row of
        metrics.csv (:attr:`rows`), the wall time since ``start`` (``time.perf_counter``), the
        ranks and where the result came from (:func:`fsi.output.provenance.describe`), the
        steps that had to be split (``retried``), the stepper's summary, the latest checkpoint
        of this run (``saved``: folder, step, t; or None), with adaptive steps those that were
        rejected for their time error and taken again shorter (``rejected``), with a periodic
        inlet the :func:`cycle_table` and after a restart where it restarted from."""
        rows, comm = self.rows, self.comm
        newton_total = sum(r.get("newton_iterations", 0) for r in rows)
        steps_done = max(len(rows), 1)
        summary = {
            "case": self.case.name,
            "structure_mode": self.case.structure.mode,
            "steps": len(rows),
            "end_time_s": rows[-1]["t"]
            if rows
            else (0.0 if self.restart is None else self.restart.t),
            "wall_time_s": wallclock.perf_counter() - start,
            "mean_step_time_s": sum(r.get("wall_time_s", 0.0) for r in rows) / steps_done,
            "newton_iterations": newton_total,
            "mean_newton_iterations": newton_total / steps_done,
            "ranks": comm.size,
            **comm.bcast(provenance.describe() if comm.rank == 0 else None),
            "retried_steps": sorted({s.index for s in retried}),
            **({} if rejected is None else {"rejected_steps": sorted({s.index for s in rejected})}),
            **self.stepper.summary(),
            "checkpoint": None if saved is None else str(saved[0]),
        }
        if self.period > 0:  # per heartbeat: the stepper's wall indices beside the rows' peaks
            summary["cycles"] = cycle_table(rows, self.period, summary.get("cycles", []))
        if self.restart is not None:
            summary["restarted_from"] = {
                "checkpoint": str(self.restart.path),
                "step": self.restart.step,
                "t": self.restart.t,
            }
        io.write_json(comm, self.out / "summary.json", summary)
        return summary

    def close(self) -> None:
        """Close every file; a failure is only logged (each row was flushed when written). The
        run's last words (why it stopped, fsi/cli.py) are added by
        :func:`fsi.output.io.append_to_log`."""
        if self._log is not None:
            io.stop_log(self._log)
            self._log = None
        files = [(w.close, w.path) for w, _ in self.writers]
        if self.table is not None:
            files.insert(0, (self.table.close, self.table.path))
        for close, path in files:
            try:
                io.collectively(self.comm, close, path)
            except io.OutputError as e:  # raised on every rank: said once
                if self.comm.rank == 0:
                    log.warning("fsi: %s", e)
        self.table, self.writers = None, []


HEADLINE = {
    "peak_velocity": max,
    "peak_pressure": max,
    "peak_displacement": max,
    "max_sss": max,
    "max_principal_cap": max,
    "min_wss": min,
    "max_wss": max,
    "recirculation_length": max,
    "inlet_flow_rate": max,
    "outlet_flow_rate": max,
    "mean_inlet_pressure": max,
}
"""The metrics columns summarised per heartbeat (:func:`cycle_table`) and how: their largest
value over the heartbeat's steps (``min_wss``: the smallest)."""

LOCATED = {
    "max_principal_cap": ("max_principal_cap_x", "max_principal_cap_y", "max_principal_cap_z")
}
"""Headline columns whose place is in metrics.csv too: the columns of its coordinates."""


def cycle_table(rows: list[dict], period: float, indices: list[dict]) -> list[dict]:
    """summary.json's ``cycles``: per heartbeat k with steps in ``rows`` (the metrics rows, by
    their ``t``): ``cycle`` k, ``start_s`` (k − 1) T, ``end_s`` its last step's t, ``steps``,
    ``complete`` (whether it reached k T), ``values`` (the :data:`HEADLINE` columns the rows
    have, plus ``indices[k − 1]``: ``min_tawss``, ``max_osi``, ``max_rrt`` of that heartbeat's
    own wall indices, where given), ``where`` (for the :data:`LOCATED` columns: the step's
    ``t`` and the point, ``x``, ``y`` (, ``z``), of the heartbeat's value; the first such
    step), ``change`` (per value, (v_k − v_{k−1}) / |v_{k−1}|; None for
    the first heartbeat or where either is missing or v_{k−1} is 0) and ``max_change`` (the
    largest |change|, None if none): the solution is periodic when ``max_change`` is small."""
    beats: dict[int, list[dict]] = {}
    for row in rows:
        beats.setdefault(heartbeat(row["t"], period), []).append(row)
    table, previous = [], {}
    for k in sorted(beats):
        values, where = {}, {}
        for column, pick in HEADLINE.items():
            found = [r for r in beats[k] if _is_finite_number(r.get(column))]
            if not found:
                continue
            row = pick(found, key=lambda r, c=column: r[c])  # the first of equal values
            values[column] = float(row[column])
            if column in LOCATED:
                point = dict(zip("xyz", (row.get(c) for c in LOCATED[column]), strict=True))
                where[column] = {"t": float(row["t"])} | {
                    axis: float(v) for axis, v in point.items() if _is_finite_number(v)
                }
        if k <= len(indices):
            values.update({key: v for key, v in indices[k - 1].items() if v is not None})
        change = {
            key: (v - previous[key]) / abs(previous[key]) if previous.get(key) else None
            for key, v in values.items()
        }
        known = [abs(c) for c in change.values() if c is not None]
        end = beats[k][-1]["t"]
        table.append(
            {
                "cycle": k,
                "start_s": (k - 1) * period,
                "end_s": end,
                "steps": len(beats[k]),
                "complete": end >= k * period * (1 - SAME_TIME),
                "values": values,
                "where": where,
                "change": change,
                "max_change": max(known) if known else None,
            }
        )
        previous = values
    return table


def _is_finite_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
