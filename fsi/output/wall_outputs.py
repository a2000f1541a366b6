"""The fluid's derived output of a step, shared by the rigid and the coupled runs
(:class:`FluidOutputs`): the viscosity, shear rate and wall shear stress fields, the wall, flow
and pressure columns of the metrics row, and the hemodynamic indices TAWSS, OSI and RRT
accumulated over the run or per heartbeat, with the ``wall_indices.csv`` written from them.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

from mpi4py import MPI

import numpy as np

from fsi import config
from fsi.geometry.tags import Boundary
from fsi.output import io, metrics
from fsi.output.columns import FLOW_COLUMNS, PRESSURE_COLUMNS, WALL_COLUMNS, heartbeat
from fsi.output.wall_indices import WallIndices
from fsi.physics import fluid, mesh
from fsi.physics.fluid_boundaries import walls

log = logging.getLogger("fsi")


class FluidOutputs:
    """The fluid's derived output: viscosity, shear rate and wall shear stress fields (on every
    no-slip or moving wall), for channel-like lumens the WALL_COLUMNS of the metrics row and,
    where the fluid mesh has an inlet and an outlet, the FLOW_COLUMNS and PRESSURE_COLUMNS; and
    the hemodynamic indices TAWSS, OSI and RRT at two Gauss points of every wall facet (three
    on a 3D wall's triangles), accumulated by :meth:`update`
    (fsi.output.wall_indices.WallIndices, docs/hemodynamic-indices.md) over the run or, when
    the inlet repeats with a period T (:func:`fsi.config.heartbeat_period`), over each heartbeat
    ((k − 1) T, k T] on its own: the accumulators start afresh at every k T and the finished
    heartbeats' are kept (:attr:`past`).

    The indices are state: :meth:`state` and :meth:`load_state` put them into the stepper's
    checkpoint (whose rows are keyed by the samples' reference coordinates, ``sampler.reference``;
    the arrays :data:`INDEX_ARRAYS`), and :meth:`write_indices` writes ``wall_indices.csv`` from
    such a state. Build it before the fluid mesh moves (the samples' reference coordinates are
    taken then)."""

    SIDES = ("", "lower", "upper")
    """``side`` of a sample: ``lower`` where the wall's normal into the lumen points up (+y),
    ``upper`` where it points down; empty off channel-like lumens (Turek–Hron)."""
    INDEX_COLUMNS = ["wall", "side", "x", "y", "TAWSS", "OSI", "RRT"]
    """wall_indices.csv: the wall's boundary label, its side, the sample's reference
    coordinates (m), TAWSS (Pa), OSI (1) and RRT (1/Pa)."""
    INDEX_ARRAYS = ("integrals", "points", "walls", "sides", "past")
    """The state's per-sample arrays ``wall_indices.<name>``, one row per owned sample (``past``:
    ``wall_indices.past.<k>``, one per finished heartbeat k); ``window`` is global."""

    def __init__(self, case: config.Case, solver: fluid.FluidSolver):
        self.solver = solver
        boundaries = mesh.boundaries(case)
        self.walls = list(walls(boundaries))
        self.lumen = not isinstance(case.geometry, config.TurekHronGeometry)
        # column → (∫ u·n ds over the boundary, compiled once; the sign that makes it positive
        # downstream): Q_in = −∫_inlet u·n ds, Q_out = ∫_outlet u·n ds.
        self.flow_rates = {}
        self.pressures = {}  # column → mean of p over the boundary (metrics.BoundaryMean)
        if Boundary.INLET in boundaries and Boundary.OUTLET in boundaries:
            for column, tag, sign in zip(
                FLOW_COLUMNS, (Boundary.INLET, Boundary.OUTLET), (-1.0, 1.0)
            ):
                form = metrics.flow_rate_form(
                    solver.u, solver.facet_tags, [tag], coordinates=solver.coordinates
                )
                self.flow_rates[column] = (form, sign)
            for column, tag in zip(
                PRESSURE_COLUMNS, (Boundary.INLET, Boundary.OUTLET), strict=True
            ):
                self.pressures[column] = metrics.BoundaryMean(
                    solver.p, solver.facet_tags, [tag], coordinates=solver.coordinates
                )
        self.columns = (
            (WALL_COLUMNS if self.lumen else [])
            + list(self.flow_rates)
            + list(self.pressures)
            + list(solver.outlet_values())
        )
        flow = metrics.WallFlow(
            solver.u, solver.p, solver.law, solver.facet_tags, self.walls, solver.coordinates
        )
        self.derived = metrics.FluidFields(flow)
        self.sampler = metrics.WallSampler(flow)
        # Steady runs: each step an independent solution, counted with its end value.
        self.interpolate = solver.scheme != "steady"
        self.components = 3 if self.sampler.gdim == 3 else 1  # the 3D indices average vectors
        self.indices = self._new_indices(time=solver.time)
        self.period = config.heartbeat_period(case)
        self.past: list[WallIndices] = []  # heartbeats 1, 2, ... before self.indices'
        self.sides = np.zeros(self.sampler.size, dtype=np.int64)
        if self.lumen and self.sampler.gdim == 2:
            normal_y = self.sampler.local().normal[:, 1]
            self.sides[normal_y > 0] = self.SIDES.index("lower")
            self.sides[normal_y < 0] = self.SIDES.index("upper")
        self.update()  # the fields of the initial state, the indices' value at the start

    def _new_indices(self, start: float = 0.0, time: float = 0.0) -> WallIndices:
        return WallIndices(
            self.sampler.size,
            start=start,
            time=time,
            interpolate=self.interpolate,
            components=self.components,
        )

    @property
    def fields(self) -> list:
        """The fluid's output fields: u, p, then the derived ones (:meth:`update`)."""
        return [self.solver.u, self.solver.p, *self.derived.fields]

    def update(self) -> dict:
        """Recompute the fields for the current solution; return the row's wall and flow
        columns. If the fluid's time has advanced since the last update (a step was taken), the
        wall shear stress now is added to the indices over that step, (t_last, t]; at the
        indices' own time (the start, a restored state) it is their value there, the start of
        the next step's interpolant."""
        s = self.solver
        self.derived.update()
        samples = self.sampler.local()
        if s.time > self.indices.time:
            self._add_step(s.time, samples.indexed)
        elif s.time == self.indices.time:  # where the next step begins: the start, a restart
            self.indices.set_value(samples.indexed)
        row = {}
        if self.lumen:
            row.update(metrics.wall_shear_summary(self.sampler.gather(samples)))
        for column, (form, sign) in self.flow_rates.items():
            row[column] = sign * metrics.total(form, s.comm) + 0.0  # −0.0 (no flow) as 0
        for column, mean in self.pressures.items():
            row[column] = mean.value()
        row.update(s.outlet_values())  # a resistance or Windkessel outlet's P (and P_c)
        return row

    def _add_step(self, t: float, tau: np.ndarray) -> None:
        """Add the step (last t, t] ending with the values ``tau`` to the indices; with a
        period T, a step that ends in a later heartbeat first closes the current one: its part
        up to the boundary k T counts for heartbeat k (τ interpolated linearly to k T, as
        WallIndices does), and the accumulators start afresh at k T from that value."""
        T = self.period
        while T > 0 and heartbeat(t, T) > len(self.past) + 1:
            boundary = (len(self.past) + 1) * T
            at_boundary = None
            if boundary > self.indices.time:
                at_boundary = self.indices.value_at(boundary, t, tau)
                self.indices.add(boundary, at_boundary)
            self.past.append(self.indices)
            # From the boundary, or from where the accumulators stopped if that is later (a
            # checkpoint of an earlier version, whose indices ran over the whole run).
            self.indices = self._new_indices(start=boundary, time=max(boundary, self.past[-1].time))
            if at_boundary is not None:
                self.indices.set_value(at_boundary)
        self.indices.add(t, tau)

    def state(self) -> dict[str, np.ndarray]:
        """The indices' accumulators, ``wall_indices.integrals`` (∫ τ dt, ∫ |τ| dt per sample)
        and ``wall_indices.window`` (the last step's time, the window's length T), and what the
        samples are: ``wall_indices.points`` (reference coordinates), ``.walls`` (facet tags),
        ``.sides`` (:data:`SIDES` indices), so that wall_indices.csv can be written from a
        checkpoint's state alone (:meth:`write_indices`). With finished heartbeats (a periodic
        inlet) also ``wall_indices.past.<k>`` (heartbeat k's integrals) and
        ``wall_indices.past_windows`` (per finished heartbeat: its last step's time and T);
        the integrals and window above are then the current heartbeat's."""
        accumulators = self.indices.state()
        state = {
            "wall_indices.integrals": accumulators["integrals"],
            "wall_indices.window": accumulators["window"],
            "wall_indices.points": self.sampler.reference.copy(),
            "wall_indices.walls": self.sampler.walls.copy(),
            "wall_indices.sides": self.sides.copy(),
        }
        if self.past:  # absent until a heartbeat is finished (a fresh stepper has none)
            finished = [indices.state() for indices in self.past]
            state.update(
                {f"wall_indices.past.{k}": a["integrals"] for k, a in enumerate(finished, start=1)}
            )
            state["wall_indices.past_windows"] = np.array([a["window"] for a in finished])
        return state

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Continue the indices from :meth:`state`'s arrays (on this run's samples); a
        checkpoint written before they existed (fsi.run.checkpoint.ADDED) starts them at the
        restart's time, with a warning."""
        if "wall_indices.integrals" not in state:
            self.indices = self._new_indices(start=self.solver.time, time=self.solver.time)
            if self.solver.comm.rank == 0:
                log.warning(
                    "fsi: the checkpoint holds no wall shear stress indices (written by "
                    "an earlier version): wall_indices.csv averages from t = %g s on",
                    self.solver.time,
                )
            return
        self.indices.load_state(
            {"integrals": state["wall_indices.integrals"], "window": state["wall_indices.window"]}
        )
        self.past = []
        for k, window in enumerate(state.get("wall_indices.past_windows", []), start=1):
            finished = self._new_indices()
            finished.load_state({"integrals": state[f"wall_indices.past.{k}"], "window": window})
            self.past.append(finished)

    def summary(self) -> dict:
        """For channel-like lumens, over every sample of their walls: ``min_tawss`` (Pa),
        ``max_osi`` and ``max_rrt`` (1/Pa) of the indices (with a period: the last heartbeat's);
        None where undefined (no step yet) or, for RRT, infinite (a zero mean shear). With a
        period also ``cycles``: those three per heartbeat, in order. Collective."""
        if not self.lumen:
            return {}
        result = self._extremes(self.indices)
        if self.period > 0:
            result["cycles"] = [self._extremes(i) for i in (*self.past, self.indices)]
        return result

    def _extremes(self, indices: WallIndices) -> dict:
        """``min_tawss``, ``max_osi``, ``max_rrt`` of ``indices`` over every rank's samples."""
        extremes = {
            "min_tawss": (indices.tawss, MPI.MIN),
            "max_osi": (indices.osi, MPI.MAX),
            "max_rrt": (indices.rrt, MPI.MAX),
        }
        result = {}
        for key, (values, op) in extremes.items():
            values = values[~np.isnan(values)]
            if len(values):
                local = float(values.min() if op == MPI.MIN else values.max())
            else:
                local = np.inf if op == MPI.MIN else -np.inf
            found = self.solver.comm.allreduce(local, op=op)
            result[key] = found if math.isfinite(found) else None
        return result

    @classmethod
    def write_indices(
        cls,
        out: Path,
        comm: MPI.Comm,
        state: dict[str, np.ndarray],
        period: float = 0.0,
        dimension: int = 2,
    ) -> None:
        """``out/wall_indices.csv`` from a stepper state that holds ``wall_indices.*`` arrays
        (:meth:`state`; nothing for one without): a row per wall sample, :data:`INDEX_COLUMNS`,
        sorted by wall, side and x; x, y (and z in ``dimension`` 3, where the indices average
        the vector τ and ``side`` is empty) in the reference configuration; an empty cell where a
        value is undefined (no step yet; OSI where there was no shear), ``inf`` for the RRT
        of a zero mean shear. With an inlet ``period`` T > 0 a first column ``cycle`` and one
        such block of rows per heartbeat the state has reached (1, 2, ...; the last one averaged
        over the part reached so far). Collective (gathered to rank 0, written there; raises
        :class:`fsi.output.io.OutputError` on every rank if it cannot be written)."""
        if "wall_indices.integrals" not in state:
            return
        windows = [*state.get("wall_indices.past_windows", []), state["wall_indices.window"]]
        beats = [state[f"wall_indices.past.{k}"] for k in range(1, len(windows))]
        beats.append(state["wall_indices.integrals"])
        where = [np.asarray(state[f"wall_indices.{name}"]) for name in ("points", "walls", "sides")]
        gathered = comm.gather((beats, where), root=0)
        rows = []
        if comm.rank == 0:
            points, walls, sides = (np.concatenate([w[i] for _, w in gathered]) for i in range(3))
            components = 3 if dimension == 3 else 1
            for k, window in enumerate(windows):
                indices = WallIndices(len(walls), components=components)
                width = components + 1
                integrals = np.concatenate([np.reshape(b[k], (-1, width)) for b, _ in gathered])
                indices.load_state({"integrals": integrals, "window": window})
                values = zip(
                    walls,
                    sides,
                    points.reshape(-1, dimension),
                    indices.tawss,
                    indices.osi,
                    indices.rrt,
                )
                cycle = [k + 1] if period > 0 else []
                rows.extend(
                    cycle
                    + [Boundary(int(wall)).label, cls.SIDES[int(side)]]
                    + [float(c) for c in point]
                    + [float(tawss), float(osi), float(rrt)]
                    for wall, side, point, tawss, osi, rrt in values
                )
            key_length = 4 if period > 0 else 3
            rows.sort(key=lambda r: tuple(r[:key_length]))
        columns = (["cycle"] if period > 0 else []) + cls.INDEX_COLUMNS
        if dimension == 3:
            columns = columns[: columns.index("y") + 1] + ["z"] + columns[columns.index("y") + 1 :]
        io.write_table(comm, out / "wall_indices.csv", columns, rows)

    def write_checkpoint_files(
        self, out: Path, comm: MPI.Comm, state: dict[str, np.ndarray]
    ) -> None:
        """The files derived from a checkpointed stepper ``state``: ``out/wall_indices.csv``
        (:meth:`write_indices`, with this run's heartbeat period). Collective."""
        self.write_indices(out, comm, state, self.period, self.sampler.gdim)
