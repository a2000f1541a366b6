"""The ``fluid`` section of a case (:class:`Fluid`): blood's density, the forms' options, the
fluid's solver settings and the inlet conditions (``inlet.kind`` picks an :data:`Inlet`; their
time-dependent data: :mod:`fsi.config.boundary_data`). The ``rheology`` and ``outlet``
subsections are :mod:`fsi.config.rheology_section`'s and :mod:`fsi.config.outlet_section`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

from fsi.config.boundary_data import FORMULA_NAMES, time_function
from fsi.config.outlet_section import BackflowForm, Outlet, TractionFreeOutlet
from fsi.config.reader import checked, non_negative, positive
from fsi.config.rheology_section import Newtonian, Rheology
from fsi.config.solver_settings import FluidSolverSettings, quadrature


@dataclass(frozen=True)
class InletPulse:
    """Inlet traction h(t) = (A/2)(1 − cos(2π t / T)) e_x for t ≤ T, 0 after (docs/model.md §2)."""

    kind: Literal["traction_pulse"] = "traction_pulse"
    amplitude: float = positive(1200.0, "Pa", ", peak")
    duration: float = positive(0.005, "s")


def _is_time_formula(text: str) -> bool:
    """True, or :class:`fsi.config.boundary_data.FormulaError` saying why ``text`` is not an
    allowed formula."""
    time_function(text)
    return True


def _formula() -> Any:
    return checked(
        "0",
        _is_time_formula,
        "an expression in t (numbers, + - * / ** %,"
        " comparisons, pi, e, " + ", ".join(FORMULA_NAMES) + ")",
    )


@dataclass(frozen=True)
class InletPressure:
    """Inlet normal traction σ n = −P(t) n (P pushes blood in) with P (Pa) a formula in t."""

    kind: Literal["pressure"] = "pressure"
    formula: str = _formula()


def _is_time_table(rows: tuple) -> bool:
    return (
        len(rows) >= 1
        and all(len(r) == 2 for r in rows)
        and all(b[0] > a[0] for a, b in zip(rows, rows[1:]))
    )


def _table(value: str) -> Any:
    return checked(
        ((0.0, 0.0),), _is_time_table, f"a non-empty list of [t, {value}] pairs with increasing t"
    )


def _period() -> Any:
    return non_negative(0.0, "s", "; 0: no repetition")


@dataclass(frozen=True)
class InletPressureTable:
    """Inlet normal traction σ n = −P(t) n from rows [t (s), P (Pa)]: linear between rows,
    constant beyond the first and last; with ``period`` T > 0, P(t) = P_table(t mod T), and the
    rows must cover [0, T] (checked by :func:`fsi.config.validate`)."""

    kind: Literal["pressure_table"] = "pressure_table"
    table: tuple[tuple[float, ...], ...] = _table("P")
    period: float = _period()


@dataclass(frozen=True)
class InletPressureFile:
    """A :class:`InletPressureTable` whose rows come from the CSV file ``file`` (relative to
    the case file's folder; to the current directory when ``--set`` gives it), read once by
    :func:`fsi.config.from_dict` into ``table`` (:func:`fsi.config.boundary_data.read_waveform`
    says what the file may hold). :func:`fsi.config.to_dict` writes it as a ``pressure_table``
    of those rows, so a run's config.yaml does not need the file."""

    kind: Literal["pressure_file"] = "pressure_file"
    file: str = ""
    period: float = _period()
    table: tuple[tuple[float, ...], ...] = ()  # filled by from_dict, not a YAML key

    quantity: ClassVar[str] = "P"  # the CSV's second column

    def as_table(self) -> InletPressureTable:
        """The inline table of the rows read (:func:`fsi.config.to_dict` writes it)."""
        return InletPressureTable(table=self.table, period=self.period)


@dataclass(frozen=True)
class ParabolicInflow:
    """Velocity inflow u = 1.5 Ū 4 s (H − s) / H² along the inward normal (s the distance along
    the inlet of width H), ramped by (1 − cos(π t / ramp_time)) / 2 for t < ramp_time
    (Turek–Hron: ramp_time 2 s; 0 = no ramp). Defaults: Turek–Hron CFD1/FSI1."""

    kind: Literal["parabolic_velocity"] = "parabolic_velocity"
    mean_velocity: float = positive(0.2, "m/s")
    ramp_time: float = non_negative(2.0, "s")


FlowProfile = Literal["parabolic", "womersley"]
"""A flow-rate inlet's velocity profile across the inlet."""


@dataclass(frozen=True)
class InletFlowRate:
    """Velocity inflow of volume flow rate Q(t) (m²/s per unit depth, positive into the domain;
    m³/s when ``geometry.axisymmetric``), a formula in t, along the inward normal: ``profile``
    ``parabolic`` u = Q 6 s (H − s)/H³ (s the distance along the inlet of width H; a pipe's
    2 Q (1 − r²/R²)/(π R²)) or ``womersley`` (the plane, or pipe, Womersley profile of each
    harmonic; needs ``period``); Q ramped by (1 − cos(π t / ramp_time))/2 for
    t < ramp_time. With ``period`` T > 0, Q(t) = Q(t mod T)."""

    kind: Literal["flow_rate"] = "flow_rate"
    formula: str = _formula()
    period: float = _period()
    profile: FlowProfile = "parabolic"
    ramp_time: float = non_negative(0.0, "s")


@dataclass(frozen=True)
class InletFlowRateTable:
    """A :class:`InletFlowRate` whose Q(t) comes from rows [t (s), Q (m²/s)], interpolated as
    :class:`InletPressureTable`'s P(t)."""

    kind: Literal["flow_rate_table"] = "flow_rate_table"
    table: tuple[tuple[float, ...], ...] = _table("Q")
    period: float = _period()
    profile: FlowProfile = "parabolic"
    ramp_time: float = non_negative(0.0, "s")


@dataclass(frozen=True)
class InletFlowRateFile:
    """A :class:`InletFlowRateTable` whose rows t, Q come from the CSV file ``file``, read as
    :class:`InletPressureFile`'s; written to config.yaml as a ``flow_rate_table``."""

    kind: Literal["flow_rate_file"] = "flow_rate_file"
    file: str = ""
    period: float = _period()
    profile: FlowProfile = "parabolic"
    ramp_time: float = non_negative(0.0, "s")
    table: tuple[tuple[float, ...], ...] = ()  # filled by from_dict, not a YAML key

    quantity: ClassVar[str] = "Q"  # the CSV's second column

    def as_table(self) -> InletFlowRateTable:
        """The inline table of the rows read (:func:`fsi.config.to_dict` writes it)."""
        return InletFlowRateTable(
            table=self.table, period=self.period, profile=self.profile, ramp_time=self.ramp_time
        )


Inlet = (
    InletPulse
    | InletPressure
    | InletPressureTable
    | InletPressureFile
    | ParabolicInflow
    | InletFlowRate
    | InletFlowRateTable
    | InletFlowRateFile
)

FLOW_RATE_INLETS = (InletFlowRate, InletFlowRateTable, InletFlowRateFile)
"""The inlets that prescribe the flow rate Q(t) (velocity inlets, as :class:`ParabolicInflow`)."""

WAVEFORM_FILES = (InletPressureFile, InletFlowRateFile)
"""The inlets whose rows are read from a CSV file (:func:`fsi.config.from_dict`)."""

TABLE_INLETS = (InletPressureTable, InletPressureFile, InletFlowRateTable, InletFlowRateFile)
"""The inlets defined by rows [t, value] (a file's read when loaded)."""


@dataclass(frozen=True)
class Fluid:
    """Blood (docs/model.md §2) and its open boundaries (docs/boundary-conditions.md compares the
    options; the defaults are the verified choice of the study's cases; docs/configuration.md).

    ``open_boundary``: the form of the inlet/outlet traction conditions, ``do_nothing``
    μ ∇u n − p n = −P n (Heywood, Rannacher & Turek 1996; exact for fully developed flow) or
    ``stress`` σ n = −P n (its tangential part forbids fully developed flow);
    ``inlet_open_boundary`` the traction inlet's own form (``same``: ``open_boundary``'s).
    ``normal_flow``:
    u·t = 0 (strongly) on a traction inlet, whose normal traction alone is prescribed, so it keeps
    its static pressure P. ``inflow_stabilization`` β ≥ 0 weights a traction inlet's backflow
    term in the ``inflow_form`` (:data:`~fsi.config.outlet_section.BackflowForm`): by default
    −β/2 ρ min(u·n, 0) u_t, which damps the tangential inflow and leaves the pressure of a normal
    inflow alone; ``full`` lowers it by β ρ (u·n)²/2 (towards a total-pressure inlet).
    ``supg``: consistent streamline-upwind/Petrov–Galerkin stabilization of the momentum equation
    (Tezduyar & Osawa's τ with a viscous limit for P2), on by default: it carries cell Reynolds
    numbers the Galerkin form cannot, Newtonian and generalized Newtonian.
    ``element``: ``p2p1`` Taylor–Hood (inf-sup stable, the default) or ``p1p1`` equal-order
    linear velocity and pressure, which needs the stabilized form's pressure terms (PSPG and
    LSIC, added with ``supg``); a fluid-only option (``structure.mode: rigid``): the interface
    maps pair the fluid's P2 velocity nodes with the solid's.
    """

    density: float = positive(1060.0, "kg/m^3")
    rheology: Rheology = field(default_factory=Newtonian)
    inlet: Inlet = field(default_factory=InletPulse)
    outlet: Outlet = field(default_factory=TractionFreeOutlet)
    open_boundary: Literal["stress", "do_nothing"] = "do_nothing"
    inlet_open_boundary: Literal["same", "stress", "do_nothing"] = "same"
    normal_flow: bool = True
    supg: bool = True
    element: Literal["p2p1", "p1p1"] = "p2p1"
    inflow_stabilization: float = non_negative(0.0)
    inflow_form: BackflowForm = "tangential_velocity"
    quadrature_degree: int = quadrature(4)
    solver: FluidSolverSettings = field(default_factory=FluidSolverSettings)
