"""The steppers of ``fsi run``, one per kind of run: each builds the mesh and the solvers of a
case, advances one step and returns the step's metrics row, and hands the loop
(:func:`fsi.run.simulation.march`) its columns, field files, summary and checkpoint state.

:class:`RigidStepper` (``structure.mode: rigid``) solves the fluid alone, with no-slip on every
wall and on the (then rigid) interface and obstacle. :class:`CoupledStepper` (the coupled modes
``fixed_wall``, ``moving_wall``; MODEL.md §4–5) solves the partitioned fluid–structure problem of
fsi/coupled/partitioned.py, Dirichlet–Neumann iterations per step. :class:`StructureStepper` solves
the structure alone (``structure.interface_load``: ``inlet_pressure`` or ``none``). The fluid's
derived output (fields, wall and flow columns, the wall shear stress indices) is
:class:`FluidOutputs`, shared by the rigid and the coupled runs.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Protocol

from mpi4py import MPI

import numpy as np

from fsi import config
from fsi.coupled import coupling, partitioned
from fsi.numerics import newton
from fsi.numerics.timestepping import Step
from fsi.output import io, metrics
from fsi.physics import fluid, mesh, solid
from fsi.physics.fluid_boundaries import boundary_conditions, inlet_pressure, walls
from fsi.physics.mesh_motion import MeshQualityError
from fsi.run import checkpoint
from fsi.run.stops import StepFailed
from fsi.run.time_control import TimeErrors
from geometry import turek_hron
from geometry.tags import Boundary, Region

log = logging.getLogger("fsi")


# --------------------------------------------------------------------------------------------
# The metrics columns


COLUMNS = [
    "step",
    "t",
    "dt",
    "peak_velocity",
    "peak_pressure",
    "peak_displacement",
    "max_sss",
    "coupling_iterations",
    "coupling_residual",
    "newton_iterations",
    "newton_residual",
    "wall_time_s",
]
COUPLED_COLUMNS = COLUMNS + [
    "peak_wall_displacement",
    "relaxation",
    "solid_newton_iterations",
    "mesh_jacobian_ratio",
]
"""``peak_wall_displacement``: max |η| over the vessel wall (0 in the fixed-wall mode);
``relaxation``: Aitken's (or the constant) ω of the step's last iteration, empty for IQN-ILS;
``newton_iterations``/``solid_newton_iterations``: fluid/solid Newton iterations summed over the
step's coupling iterations; ``mesh_jacobian_ratio``: the fluid mesh's smallest J/J_ref."""
WALL_COLUMNS = ["min_wss", "max_wss", "recirculation_length"]
"""Channel-like lumens (stenosis, channel): the signed wall shear stress's extremes (Pa) and the
longest reversed-flow zone along either wall (m) (fsi.output.metrics.wall_shear_summary)."""


def stress_columns(solver: solid.SolidSolver) -> list[str]:
    """The structure's stress maxima (Pa) beside ``max_sss``: ``max_von_mises``,
    ``max_principal`` over the whole structure, and ``max_sss_<region>``,
    ``max_von_mises_<region>``, ``max_principal_<region>`` per region (cap, lipid, wall; the
    Turek–Hron flag), where ``max_sss`` is the largest |σ₁₂|
    (fsi.physics.solid_stress.StressFields); with a fibrous cap, :data:`CAP_LOCATION_COLUMNS`."""
    return (
        ["max_von_mises", "max_principal"]
        + [
            f"{name}_{region.label}"
            for region in solver.regions
            for name in ("max_sss", "max_von_mises", "max_principal")
        ]
        + (CAP_LOCATION_COLUMNS if Region.CAP in solver.regions else [])
    )


CAP_LOCATION_COLUMNS = ["max_principal_cap_x", "max_principal_cap_y"]
"""Where ``max_principal_cap`` is attained: the reference coordinates (m) of the stress
field's node that holds it (fsi.physics.solid_stress.StressFields.location_of_max)."""


def stress_row(solver: solid.SolidSolver) -> dict[str, float]:
    """``max_sss`` and the :func:`stress_columns` of the current stresses (call
    ``solver.stress.update()`` first). Collective."""
    row = {}
    for label, m in solver.stress.region_maxima().items():
        suffix = "" if label == "all" else f"_{label}"
        row.update(
            {
                f"max_sss{suffix}": m.max_abs_shear,
                f"max_von_mises{suffix}": m.max_von_mises,
                f"max_principal{suffix}": m.max_principal,
            }
        )
    if Region.CAP in solver.regions:
        _, x, y = solver.stress.location_of_max("max_principal", Region.CAP)
        row.update(zip(CAP_LOCATION_COLUMNS, (x, y), strict=True))
    return row


FLOW_COLUMNS = ["inlet_flow_rate", "outlet_flow_rate"]
"""Every fluid mesh with an inlet and an outlet: the volume flow rate per unit depth (m²/s)
through each, positive downstream, on the current mesh (fsi.output.metrics.flow_rate)."""
PRESSURE_COLUMNS = ["mean_inlet_pressure", "mean_outlet_pressure"]
"""Every fluid mesh with an inlet and an outlet: the pressure p averaged over the inlet and
over the outlet (Pa; in 2D the length average ∫ p ds / ∫ ds, on the current mesh;
fsi.output.metrics.BoundaryMean)."""


# --------------------------------------------------------------------------------------------
# Heartbeats


def heartbeat(t: float, period: float) -> int:
    """The 1-based number k of the heartbeat (k − 1) T < t <= k T that holds time ``t`` (a step
    ending on k T belongs to heartbeat k; times within 1e-9 T of k T count as on it); 1 for
    t <= T."""
    return max(1, math.ceil(t / period - 1e-9))


# --------------------------------------------------------------------------------------------
# What a stepper is


def global_dofs(V) -> int:
    """Number of degrees of freedom of a function space over all ranks."""
    return V.dofmap.index_map.size_global * V.dofmap.index_map_bs


class Stepper(Protocol):
    """One kind of run: its columns, its field files and how it advances one step."""

    columns: list[str]

    def field_files(self) -> dict[str, tuple[object, list]]:
        """File name → (mesh, fields) of each field time series (the fields are Functions
        whose values change in place)."""

    def step(self, step: Step) -> dict:
        """Advance one step; return its metrics row (raise :class:`StepFailed` on failure)."""

    def describe(self, row: dict) -> str:
        """The step's solver statistics for the progress log."""

    def summary(self) -> dict:
        """Totals and sizes for summary.json."""

    def state(self) -> dict[str, np.ndarray]:
        """Everything the next steps depend on, as named local arrays (a checkpoint): the
        solvers' state and history, the coupling's memory, the counters of :meth:`summary`."""

    def layouts(self) -> dict[str, checkpoint.Layout]:
        """Where the rows of the distributed arrays of :meth:`state` live (array name or name
        prefix → layout; the others are global), taken from the reference configuration when
        the stepper is built."""

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Continue from :meth:`state`'s arrays (on this run's dofs, :func:`fsi.run.checkpoint.
        localize`); the output fields are brought up to date."""

    def forget_jacobians(self) -> None:
        """Drop the Jacobians the solvers keep across steps (``solver.jacobian_reuse: run``), so
        the next step goes on as one restarted from :meth:`state` would."""


# --------------------------------------------------------------------------------------------
# Fluid outputs shared by the rigid and the coupled runs


class FluidOutputs:
    """The fluid's derived output: viscosity, shear rate and wall shear stress fields (on every
    no-slip or moving wall), for channel-like lumens the WALL_COLUMNS of the metrics row and,
    where the fluid mesh has an inlet and an outlet, the FLOW_COLUMNS and PRESSURE_COLUMNS; and
    the hemodynamic indices TAWSS, OSI and RRT at two Gauss points of every wall facet,
    accumulated by :meth:`update` (fsi.output.metrics.WallIndices, docs/hemodynamic-indices.md) over
    the run or, when the inlet repeats with a period T
    (:func:`fsi.config.heartbeat_period`), over each heartbeat ((k − 1) T, k T] on its own:
    the accumulators start afresh at every k T and the finished heartbeats' are kept
    (:attr:`past`).

    The indices are state: :meth:`state`, :meth:`layouts` and :meth:`load_state` put them into
    the stepper's checkpoint, keyed by the samples' reference coordinates, and
    :meth:`write_indices` writes ``wall_indices.csv`` from such a state. Build it before the
    fluid mesh moves (the samples' reference coordinates are taken then)."""

    SIDES = ("", "lower", "upper")
    """``side`` of a sample: ``lower`` where the wall's normal into the lumen points up (+y),
    ``upper`` where it points down; empty off channel-like lumens (Turek–Hron)."""
    INDEX_COLUMNS = ["wall", "side", "x", "y", "TAWSS", "OSI", "RRT"]
    """wall_indices.csv: the wall's boundary label, its side, the sample's reference
    coordinates (m), TAWSS (Pa), OSI (1) and RRT (1/Pa)."""
    INDEX_ARRAYS = ("integrals", "points", "walls", "sides", "past")
    """The state's per-sample arrays ``wall_indices.<name>`` (:meth:`layouts`; ``past``:
    ``wall_indices.past.<k>``, one per finished heartbeat k)."""

    def __init__(self, case: config.Case, solver: fluid.FluidSolver):
        self.solver = solver
        boundaries = mesh.geometry_module(case).BOUNDARIES
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
                form = metrics.flow_rate_form(solver.u, solver.facet_tags, [tag])
                self.flow_rates[column] = (form, sign)
            for column, tag in zip(
                PRESSURE_COLUMNS, (Boundary.INLET, Boundary.OUTLET), strict=True
            ):
                self.pressures[column] = metrics.BoundaryMean(solver.p, solver.facet_tags, [tag])
        self.columns = (
            (WALL_COLUMNS if self.lumen else [])
            + list(self.flow_rates)
            + list(self.pressures)
            + list(solver.outlet_values())
        )
        flow = metrics.WallFlow(solver.u, solver.p, solver.law, solver.facet_tags, self.walls)
        self.derived = metrics.FluidFields(flow)
        self.sampler = metrics.WallSampler(flow)
        # Steady runs: each step an independent solution, counted with its end value.
        self.interpolate = solver.scheme != "steady"
        self.indices = metrics.WallIndices(
            self.sampler.size, time=solver.time, interpolate=self.interpolate
        )
        self.period = config.heartbeat_period(case)
        self.past: list[metrics.WallIndices] = []  # heartbeats 1, 2, ... before self.indices'
        self.sides = np.zeros(self.sampler.size, dtype=np.int64)
        if self.lumen:
            normal_y = self.sampler.local().normal[:, 1]
            self.sides[normal_y > 0] = self.SIDES.index("lower")
            self.sides[normal_y < 0] = self.SIDES.index("upper")
        self._layout = checkpoint.interface_layout("wall_samples", self.sampler.reference, 1)
        self.update()  # the fields of the initial state, the indices' value at the start

    @property
    def fields(self) -> list:
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
            self._add_step(s.time, samples.tau)
        elif s.time == self.indices.time:  # where the next step begins: the start, a restart
            self.indices.set_value(samples.tau)
        row = {}
        if self.lumen:
            row.update(metrics.wall_shear_summary(self.sampler.gather(samples)))
        for column, (form, sign) in self.flow_rates.items():
            row[column] = sign * metrics.total(form, s.comm)
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
            self.indices = metrics.WallIndices(
                self.sampler.size,
                start=boundary,
                time=max(boundary, self.past[-1].time),
                interpolate=self.interpolate,
            )
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

    def layouts(self) -> dict[str, checkpoint.Layout]:
        """The per-sample arrays of :meth:`state`: one row per owned sample, keyed by its
        reference coordinates (``window`` is global)."""
        return {f"wall_indices.{name}": self._layout for name in self.INDEX_ARRAYS}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Continue the indices from :meth:`state`'s arrays (on this run's samples); a
        checkpoint written before they existed (fsi.run.checkpoint.ADDED) starts them at the
        restart's time, with a warning."""
        if "wall_indices.integrals" not in state:
            self.indices = metrics.WallIndices(
                self.sampler.size,
                start=self.solver.time,
                time=self.solver.time,
                interpolate=self.interpolate,
            )
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
            finished = metrics.WallIndices(self.sampler.size)
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

    def _extremes(self, indices: metrics.WallIndices) -> dict:
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
        cls, out: Path, comm: MPI.Comm, state: dict[str, np.ndarray], period: float = 0.0
    ) -> None:
        """``out/wall_indices.csv`` from a stepper state that holds ``wall_indices.*`` arrays
        (:meth:`state`; nothing for one without): a row per wall sample, :data:`INDEX_COLUMNS`,
        sorted by wall, side and x; x, y in the reference configuration; an empty cell where a
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
            for k, window in enumerate(windows):
                indices = metrics.WallIndices(len(walls))
                integrals = np.concatenate([np.reshape(b[k], (-1, 2)) for b, _ in gathered])
                indices.load_state({"integrals": integrals, "window": window})
                values = zip(
                    walls, sides, points.reshape(-1, 2), indices.tawss, indices.osi, indices.rrt
                )
                cycle = [k + 1] if period > 0 else []
                rows.extend(
                    cycle
                    + [
                        Boundary(int(wall)).label,
                        cls.SIDES[int(side)],
                        float(x),
                        float(y),
                        float(tawss),
                        float(osi),
                        float(rrt),
                    ]
                    for wall, side, (x, y), tawss, osi, rrt in values
                )
            key_length = 4 if period > 0 else 3
            rows.sort(key=lambda r: tuple(r[:key_length]))
        columns = (["cycle"] if period > 0 else []) + cls.INDEX_COLUMNS
        io.write_table(comm, out / "wall_indices.csv", columns, rows)


# --------------------------------------------------------------------------------------------
# Rigid structure: the fluid alone


def fluid_boundaries(case: config.Case) -> tuple:
    """Rigid structure: the configured inlet and outlet, no-slip on every wall
    (fsi.physics.fluid_boundaries.boundary_conditions)."""
    return boundary_conditions(
        case.fluid, mesh.geometry_module(case).BOUNDARIES, moving_interface=False
    )


class RigidStepper:
    """The fluid alone on the fixed fluid mesh (Turek–Hron cases add drag and lift)."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        self.whole = mesh.build(case, comm)
        self.part = mesh.restrict(self.whole, Region.FLUID)
        self.cells = mesh.summary(self.whole, case)["cells"]
        self.solver = fluid.FluidSolver(
            self.part.mesh,
            self.part.facet_tags,
            case.fluid,
            fluid_boundaries(case),
            scheme=case.time.scheme,
        )
        self.obstacle = [
            b
            for b in (Boundary.OBSTACLE, Boundary.INTERFACE)
            if b in mesh.geometry_module(case).BOUNDARIES
        ]
        self.turek_hron = isinstance(case.geometry, config.TurekHronGeometry)
        self.outputs = FluidOutputs(case, self.solver)
        self._layouts = fluid_layouts(self.solver)
        self.time_errors = time_errors(case, comm, {"fluid": (self.solver.u, self._layouts)})
        self.columns = (
            COLUMNS
            + self.outputs.columns
            + (["drag", "lift"] if self.turek_hron else [])
            + self.time_errors.columns
        )

    def field_files(self) -> dict[str, tuple[object, list]]:
        return {"fields.xdmf": (self.part.mesh, self.outputs.fields)}

    def forget_jacobians(self) -> None:
        self.solver.newton.callbacks.forget()

    def step(self, step: Step) -> dict:
        solver = self.solver
        result = solver.step(step.t, step.dt)
        if not result.converged:
            raise StepFailed(result.reason)
        solver.advance()
        row = {
            "peak_velocity": metrics.peak_velocity(solver.u),
            "peak_pressure": metrics.peak_pressure(solver.p),
            "peak_displacement": 0.0,
            "coupling_iterations": 0,
            "newton_iterations": result.iterations,
            "newton_residual": result.residual,
            **self.outputs.update(),
            **self.time_errors.after_step(step.t),
        }
        if self.turek_hron:
            row["drag"], row["lift"] = solver.boundary_force(self.obstacle)
        return row

    def describe(self, row: dict) -> str:
        return f"Newton {row['newton_iterations']} (residual {row['newton_residual']:.2e})"

    def summary(self) -> dict:
        W = self.solver.W
        return {
            "mean_coupling_iterations": 0.0,
            "fluid_dofs": global_dofs(W),
            "cells": self.cells,
            **self.outputs.summary(),
        }

    def state(self) -> dict[str, np.ndarray]:
        return {
            **checkpoint.to_arrays("fluid.", self.solver.save_state()),
            **self.outputs.state(),
            **self.time_errors.state(),
        }

    def layouts(self) -> dict[str, checkpoint.Layout]:
        return {**self._layouts, **self.outputs.layouts(), **self.time_errors.layouts()}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        self.solver.restore_state(fluid_state(self.solver, state))
        self.outputs.load_state(state)
        self.outputs.update()
        self.time_errors.load_state(state, self.solver.time)


# --------------------------------------------------------------------------------------------
# The coupled modes: partitioned fluid–structure interaction


class CoupledStepper:
    """Dirichlet–Neumann iterations per step (fsi/coupled/partitioned.py), then the study's metrics:
    peaks of |u| and p over the fluid, of |η| over the structure, and the largest |σ₁₂| (SSS).
    The Turek–Hron cases add the benchmark's ``drag`` and ``lift`` (N/m, over the cylinder and
    the flag, on the deformed mesh) and the displacement ``ux_A``, ``uy_A`` (m) of point A."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        self.problem = partitioned.build_coupled(case, comm)
        self.cells = mesh.summary(self.problem.whole, case)["cells"]
        self.point_a = (
            turek_hron.point_a(case.geometry)
            if isinstance(case.geometry, config.TurekHronGeometry)
            else None
        )
        self.outputs = FluidOutputs(case, self.problem.fluid)
        # Before the mesh ever moves: the checkpoint keys are reference coordinates.
        p = self.problem
        interface = checkpoint.interface_layout("interface", p.solid.interface_points, 2)
        self._layouts = {
            **fluid_layouts(p.fluid),
            **structure_layouts(p.solid),
            "coupling.iqn.V": interface,
            "coupling.iqn.W": interface,
            "predictor.values": interface,
        }
        self.time_errors = time_errors(
            case,
            comm,
            {"fluid": (p.fluid.u, self._layouts), "structure": (p.solid.eta, self._layouts)},
        )
        self.columns = (
            COUPLED_COLUMNS
            + stress_columns(p.solid)
            + self.outputs.columns
            + (["drag", "lift", "ux_A", "uy_A"] if self.point_a else [])
            + self.time_errors.columns
        )
        self.iterations: list[int] = []
        self.solid_newton = 0

    def field_files(self) -> dict[str, tuple[object, list]]:
        p = self.problem
        return {
            "fields.xdmf": (p.fluid.mesh, [*self.outputs.fields, p.fluid.ale.d]),
            "solid.xdmf": (
                p.solid.domain.mesh,
                [p.solid.eta, *p.solid.stress.cell_fields.values()],
            ),
        }

    def forget_jacobians(self) -> None:
        self.problem.fluid.newton.callbacks.forget()
        self.problem.solid.newton.callbacks.forget()

    def step(self, step: Step) -> dict:
        p = self.problem
        try:
            result = p.step(step.index, step.t, step.dt)
        except coupling.CouplingNotConverged as e:
            raise StepFailed(f"{e} (t = {step.t:g} s, dt = {step.dt:g} s)") from e
        except (newton.SolveFailed, MeshQualityError) as e:
            raise StepFailed(
                f"step {step.index} to t = {step.t:g} s (dt = {step.dt:g} s), "
                f"coupling iteration {p.fluid_side.solves}: {e}"
            ) from e
        p.solid.stress.update()
        fluid_last = p.fluid_side.last
        self.iterations.append(result.iterations)
        self.solid_newton += p.solid_side.newton_iterations
        omega = p.relaxation
        row = (
            self.benchmark_values()
            if self.point_a
            else {"peak_wall_displacement": p.solid.max_displacement([Region.WALL])}
        )
        return {
            **row,
            **self.outputs.update(),
            "peak_velocity": metrics.peak_velocity(p.fluid.u),
            "peak_pressure": metrics.peak_pressure(p.fluid.p),
            "peak_displacement": p.solid.max_displacement(),
            **stress_row(p.solid),
            "coupling_iterations": result.iterations,
            "coupling_residual": result.residuals[-1],
            "newton_iterations": p.fluid_side.newton_iterations,
            "newton_residual": fluid_last.residual if fluid_last else "",
            "relaxation": "" if omega is None else omega,
            "solid_newton_iterations": p.solid_side.newton_iterations,
            "mesh_jacobian_ratio": p.fluid_side.mesh_quality,
            **self.time_errors.after_step(step.t),
        }

    def benchmark_values(self) -> dict:
        """Turek–Hron: drag and lift on the cylinder + flag, the displacement of point A."""
        p = self.problem
        drag, lift = p.fluid.boundary_force((Boundary.OBSTACLE, Boundary.INTERFACE))
        ux, uy = metrics.nodal_value(p.solid.eta, self.point_a)
        return {"drag": drag, "lift": lift, "ux_A": ux, "uy_A": uy}

    def describe(self, row: dict) -> str:
        omega = row["relaxation"]
        return (
            f"coupling {row['coupling_iterations']} (residual "
            f"{row['coupling_residual']:.1e}{'' if omega == '' else f', ω = {omega:.3g}'})"
            f"  Newton fluid {row['newton_iterations']}, solid "
            f"{row['solid_newton_iterations']}  |η|max {row['peak_displacement']:.3g} m"
        )

    def summary(self) -> dict:
        p, n = self.problem, len(self.iterations)
        W, V = p.fluid.W, p.solid.V
        return {
            "acceleration": p.settings.acceleration,
            "coupling_iterations": sum(self.iterations),
            "mean_coupling_iterations": sum(self.iterations) / max(n, 1),
            "max_coupling_iterations": max(self.iterations, default=0),
            "solid_newton_iterations": self.solid_newton,
            "fluid_dofs": global_dofs(W),
            "solid_dofs": global_dofs(V),
            "cells": self.cells,
            **self.outputs.summary(),
        }

    def state(self) -> dict[str, np.ndarray]:
        """The fluid's (solution, BDF history, mesh displacement history, step counter) and the
        solid's (η, Newmark/generalized-α history, loads) states, the acceleration's memory
        (Aitken's ω, IQN-ILS's columns of past steps), the predictor's history, the counters,
        the wall indices' accumulators (:meth:`FluidOutputs.state`)."""
        p = self.problem
        return {
            **checkpoint.to_arrays("fluid.", p.fluid.save_state()),
            **self.outputs.state(),
            **checkpoint.to_arrays("solid.", p.solid.save_state()),
            **{f"coupling.{k}": v for k, v in p.acceleration.state().items()},
            **{f"predictor.{k}": v for k, v in p.predictor.state().items()},
            "counters.coupling_iterations": np.array(self.iterations, dtype=np.int64),
            "counters.solid_newton_iterations": np.array(self.solid_newton),
            **self.time_errors.state(),
        }

    def layouts(self) -> dict[str, checkpoint.Layout]:
        return {**self._layouts, **self.outputs.layouts(), **self.time_errors.layouts()}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        p = self.problem
        p.fluid.restore_state(fluid_state(p.fluid, state))
        _load_solid(p.solid, state)
        p.acceleration.load_state(checkpoint.subset("coupling.", state))
        p.predictor.load_state(checkpoint.subset("predictor.", state))
        self.iterations = [int(n) for n in state["counters.coupling_iterations"]]
        self.solid_newton = int(state["counters.solid_newton_iterations"])
        self.outputs.load_state(state)
        self.outputs.update()
        self.time_errors.load_state(state, p.fluid.time)


# --------------------------------------------------------------------------------------------
# The structure alone (structure.interface_load: inlet_pressure or none)


class StructureStepper:
    """The structure alone under a prescribed interface pressure (the inlet's P(t)) or under its
    body force only; the fluid columns hold the prescribed pressure and no velocity. The
    Turek–Hron cases (CSM1–3) add the displacement ``ux_A``, ``uy_A`` (m) of point A, as the
    coupled runs do."""

    def __init__(self, case: config.Case, comm: MPI.Comm):
        whole = mesh.build(case, comm)
        self.cells = mesh.summary(whole, case)["cells"]
        self.pressure = (
            inlet_pressure(case.fluid.inlet)
            if case.structure.interface_load == "inlet_pressure"
            else None
        )
        self.solver = solid.build(case, whole, comm, self.pressure)
        self.stenosis = isinstance(case.geometry, config.StenosisGeometry)
        self.point_a = (
            turek_hron.point_a(case.geometry)
            if isinstance(case.geometry, config.TurekHronGeometry)
            else None
        )
        self.columns = (
            COLUMNS
            + ["peak_wall_displacement"]
            + stress_columns(self.solver)
            + (["ux_A", "uy_A"] if self.point_a else [])
        )
        self._layouts = structure_layouts(self.solver)
        self.time_errors = time_errors(case, comm, {"structure": (self.solver.eta, self._layouts)})
        self.columns += self.time_errors.columns

    def field_files(self) -> dict[str, tuple[object, list]]:
        s = self.solver
        return {"solid.xdmf": (s.domain.mesh, [s.eta, *s.stress.cell_fields.values()])}

    def forget_jacobians(self) -> None:
        self.solver.newton.callbacks.forget()

    def step(self, step: Step) -> dict:
        s = self.solver
        result = s.step(step.t, step.dt)
        if not result.converged:
            raise StepFailed(
                f"structure step {step.index} to t = {step.t:g} s failed: "
                f"{result.reason} (residual {result.residual:.3g})"
            )
        s.advance()
        s.stress.update()
        row = {
            "peak_velocity": "",
            "peak_pressure": self.pressure(step.t) if self.pressure else "",
            "peak_displacement": s.max_displacement(),
            "peak_wall_displacement": (s.max_displacement([Region.WALL]) if self.stenosis else ""),
            **stress_row(s),
            "coupling_iterations": 0,
            "newton_iterations": result.iterations,
            "newton_residual": result.residual,
            **self.time_errors.after_step(step.t),
        }
        if self.point_a:
            row["ux_A"], row["uy_A"] = metrics.nodal_value(s.eta, self.point_a)
        return row

    def describe(self, row: dict) -> str:
        return (
            f"Newton {row['newton_iterations']} (residual {row['newton_residual']:.2e})  "
            f"|η|max {row['peak_displacement']:.3g} m  SSS {row['max_sss']:.3g} Pa"
        )

    def summary(self) -> dict:
        V = self.solver.V
        return {"mean_coupling_iterations": 0.0, "solid_dofs": global_dofs(V), "cells": self.cells}

    def state(self) -> dict[str, np.ndarray]:
        return {
            **checkpoint.to_arrays("solid.", self.solver.save_state()),
            **self.time_errors.state(),
        }

    def layouts(self) -> dict[str, checkpoint.Layout]:
        return {**self._layouts, **self.time_errors.layouts()}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        _load_solid(self.solver, state)
        self.time_errors.load_state(state, self.solver.t)


# --------------------------------------------------------------------------------------------
# Adaptive steps: the local time error of the controlled fields (fsi/run/time_control.py)

FIELD_LAYOUTS = {"fluid": "fluid.u_n", "structure": "solid.eta"}
"""The checkpoint layout of each controlled field's values (those of its history's)."""


def time_errors(case: config.Case, comm: MPI.Comm, fields: dict) -> TimeErrors:
    """The :class:`TimeErrors` of ``fields`` (name → (Function, the stepper's layouts)) with
    ``time.step_control: adaptive`` (their values at t = 0 the first level), else of none."""
    adaptive = case.time.step_control == "adaptive"
    settings = case.time.adaptive
    return TimeErrors(
        comm,
        {
            name: (f, layouts[FIELD_LAYOUTS[name]])
            for name, (f, layouts) in fields.items()
            if adaptive
        },
        0.0,
        {"fluid": settings.velocity_scale, "structure": settings.displacement_scale},
    )


# --------------------------------------------------------------------------------------------
# Checkpoint layouts of the solvers' states


def fluid_layouts(solver: fluid.FluidSolver) -> dict[str, checkpoint.Layout]:
    """The rows of :class:`fsi.physics.fluid.FluidState`'s arrays: ``U`` on the mixed space
    (velocity and pressure nodes), ``u_n``/``u_nm1`` on the velocity's P2 nodes, the mesh
    displacement history and ``w`` on the P1 vertices. Call it before the mesh moves."""
    velocity = checkpoint.space_layout("fluid_velocity", solver.V)
    pressure = checkpoint.space_layout("fluid_pressure", solver.Q)
    V_to_W, Q_to_W = solver.mixed_dofs()
    mixed = checkpoint.mixed_layout(
        "fluid_mixed", solver.W, [(V_to_W, velocity), (Q_to_W, pressure)]
    )
    vertices = checkpoint.space_layout("fluid_vertices", solver.ale.space)
    return {
        "fluid.U": mixed,
        "fluid.u_n": velocity,
        "fluid.u_nm1": velocity,
        **{f"fluid.{name}": vertices for name in ("d", "d_n", "d_nm1", "w")},
    }


def fluid_state(solver: fluid.FluidSolver, state: dict[str, np.ndarray]) -> fluid.FluidState:
    """The fluid's state from ``fluid.*`` arrays. The lumped outlets' state (a Windkessel's
    P_c^n, P_c^{n−1}; fsi.run.checkpoint.VARIABLE) is restored if it fits this run's outlets; one
    that does not (a checkpoint written before outlets had a state, or by a run with another
    kind of outlet) starts them from their initial state (P_0), with a warning."""
    initial = np.concatenate([np.zeros(0), *(o.model.initial_state() for o in solver.lumped)])
    stored = state.get("fluid.outlet_state")
    if stored is None or stored.shape != initial.shape:
        if initial.size and solver.comm.rank == 0:
            log.warning(
                "fsi: the checkpoint holds no state of this run's fluid.outlet (written "
                "with another kind of outlet): it starts from its initial_pressure at "
                "t = %g s",
                float(state["fluid.time"]),
            )
        state = {**state, "fluid.outlet_state": initial}
    return checkpoint.from_arrays(fluid.FluidState, "fluid.", state)


def structure_layouts(solver: solid.SolidSolver) -> dict[str, checkpoint.Layout]:
    """The rows of :class:`fsi.physics.solid.SolidState`'s arrays: η and its history, the tractions
    on the displacement space's nodes; the nodal interface forces, arrays (n, 2), on the owned
    interface nodes (one row each)."""
    nodes = checkpoint.space_layout("solid", solver.V)
    forces = checkpoint.interface_layout("interface_nodes", solver.interface_points, 1)
    return {
        **{
            f"solid.{name}": nodes
            for name in ("eta", "eta_n", "v_n", "a_n", "traction", "traction_n")
        },
        "solid.forces": forces,
        "solid.forces_n": forces,
    }


def _load_solid(solver: solid.SolidSolver, state: dict[str, np.ndarray]) -> None:
    """The solid's state from ``solid.*`` arrays; the rates of the last step η̇, η̈ (outputs,
    recomputed by every step) as :meth:`fsi.physics.solid.SolidSolver.advance` leaves them;
    stresses."""
    solver.restore_state(checkpoint.from_arrays(solid.SolidState, "solid.", state))
    solver.v.x.array[:] = solver.v_n.x.array
    solver.a.x.array[:] = solver.a_n.x.array
    solver.stress.update()
