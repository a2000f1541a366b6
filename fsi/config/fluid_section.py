"""The ``fluid`` section of a case (:class:`Fluid`): blood's density, the forms' options, the
fluid's solver settings and the inlet conditions (``inlet.kind`` picks an :data:`Inlet`; their
time-dependent data: :mod:`fsi.config.boundary_data`). The ``rheology`` and ``outlet``
subsections are :mod:`fsi.config.rheology_section`'s and :mod:`fsi.config.outlet_section`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from fsi.config.boundary_data import FORMULA_NAMES, time_function
from fsi.config.outlet_section import Outlet, TractionFreeOutlet
from fsi.config.reader import checked, non_negative, positive
from fsi.config.rheology_section import Newtonian, Rheology
from fsi.config.solver_settings import SolverSettings, quadrature


@dataclass(frozen=True)
class InletPulse:
    """Inlet traction h(t) = (A/2)(1 − cos(2π t / T)) e_x for t ≤ T, 0 after (docs/model.md §2)."""

    kind: Literal["traction_pulse"] = "traction_pulse"
    amplitude: float = positive(1200.0, " (Pa, peak)")
    duration: float = positive(0.005, " (s)")


def _is_time_formula(text: str) -> bool:
    """True, or :class:`fsi.config.boundary_data.FormulaError` saying why ``text`` is not an
    allowed formula."""
    time_function(text)
    return True


@dataclass(frozen=True)
class InletPressure:
    """Inlet normal traction σ n = −P(t) n (P pushes blood in) with P (Pa) a formula in t."""

    kind: Literal["pressure"] = "pressure"
    formula: str = checked(
        "0",
        _is_time_formula,
        "an expression in t (numbers, + - * / ** %,"
        " comparisons, pi, e, " + ", ".join(FORMULA_NAMES) + ")",
    )


def _is_time_table(rows: tuple) -> bool:
    return (
        len(rows) >= 1
        and all(len(r) == 2 for r in rows)
        and all(b[0] > a[0] for a, b in zip(rows, rows[1:]))
    )


def _period() -> Any:
    return non_negative(0.0, " (s; 0: no repetition)")


@dataclass(frozen=True)
class InletPressureTable:
    """Inlet normal traction σ n = −P(t) n from rows [t (s), P (Pa)]: linear between rows,
    constant beyond the first and last; with ``period`` T > 0, P(t) = P_table(t mod T), and the
    rows must cover [0, T] (checked by :func:`fsi.config.validate`)."""

    kind: Literal["pressure_table"] = "pressure_table"
    table: tuple[tuple[float, ...], ...] = checked(
        ((0.0, 0.0),), _is_time_table, "a non-empty list of [t, P] pairs with increasing t"
    )
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


@dataclass(frozen=True)
class ParabolicInflow:
    """Velocity inflow u = 1.5 Ū 4 s (H − s) / H² along the inward normal (s the distance along
    the inlet of width H), ramped by (1 − cos(π t / ramp_time)) / 2 for t < ramp_time
    (Turek–Hron: ramp_time 2 s; 0 = no ramp). Defaults: Turek–Hron CFD1/FSI1."""

    kind: Literal["parabolic_velocity"] = "parabolic_velocity"
    mean_velocity: float = positive(0.2, " (m/s)")
    ramp_time: float = non_negative(2.0, " (s)")


Inlet = InletPulse | InletPressure | InletPressureTable | InletPressureFile | ParabolicInflow


@dataclass(frozen=True)
class Fluid:
    """Blood (docs/model.md §2) and its open boundaries (docs/boundary-conditions.md compares the
    options; the defaults are the verified choice of the study's cases; docs/configuration.md).

    ``open_boundary``: the form of the inlet/outlet traction conditions, ``do_nothing``
    μ ∇u n − p n = −P n (Heywood, Rannacher & Turek 1996; exact for fully developed flow) or
    ``stress`` σ n = −P n (its tangential part forbids fully developed flow). ``normal_flow``:
    u·t = 0 (strongly) on a traction inlet, whose normal traction alone is prescribed, so it keeps
    its static pressure P. ``inflow_stabilization`` β ≥ 0 adds −β/2 ρ min(u·n, 0) u to a traction
    inlet's σ n, lowering its pressure by β ρ (u·n)²/2 (towards a total-pressure inlet).
    ``supg``: consistent streamline-upwind/Petrov–Galerkin stabilization of the momentum equation
    (Tezduyar & Osawa's τ), for an inlet cell Reynolds number too high for the Galerkin form.
    """

    density: float = positive(1060.0, " (kg/m^3)")
    rheology: Rheology = field(default_factory=Newtonian)
    inlet: Inlet = field(default_factory=InletPulse)
    outlet: Outlet = field(default_factory=TractionFreeOutlet)
    open_boundary: Literal["stress", "do_nothing"] = "do_nothing"
    normal_flow: bool = True
    supg: bool = False
    inflow_stabilization: float = non_negative(0.0)
    quadrature_degree: int = quadrature(4)
    solver: SolverSettings = field(default_factory=SolverSettings)
