"""The ``fluid`` section of a case: blood's rheology, the inlet and outlet conditions, the
forms' options and the fluid's solver settings (:class:`Fluid`).

The sections chosen by a tag are unions of small dataclasses: ``rheology.model`` picks a
:data:`Rheology` (the laws themselves are in :mod:`fsi.physics.rheology`, looked up by this
tag), ``inlet.kind`` an :data:`Inlet` (time-dependent data: :mod:`fsi.config.boundary_data`),
``outlet.kind`` an :data:`Outlet` (:mod:`fsi.physics.outlets`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from fsi.config.boundary_data import FORMULA_NAMES, time_function
from fsi.config.reader import checked, non_negative, positive
from fsi.config.solver_settings import SolverSettings, quadrature


@dataclass(frozen=True)
class Newtonian:
    model: Literal["newtonian"] = "newtonian"
    viscosity: float = positive(0.0035, " (Pa s)")


@dataclass(frozen=True)
class PlateauLaw:
    """The laws whose viscosity goes from μ0 (``mu_0``) at rest to μ∞ (``mu_inf``) at high
    shear rates, changing around the shear rate 1/λ (``relaxation_time`` λ): Carreau,
    Carreau–Yasuda and Cross. These defaults are the study's Carreau law's (MODEL.md §2); the
    other two laws have their own."""

    model: str
    mu_0: float = positive(0.0456, " (Pa s)")
    mu_inf: float = positive(0.0032, " (Pa s)")
    relaxation_time: float = positive(10.03, " (s)")


@dataclass(frozen=True)
class Carreau(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)²)^((n − 1)/2). Defaults: the study's (MODEL.md §2)."""

    model: Literal["carreau"] = "carreau"
    power_index: float = positive(0.344)


@dataclass(frozen=True)
class CarreauYasuda(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)^a)^((n − 1)/a). Defaults: blood (Cho & Kensey 1991, as
    used by Johnston et al. 2004)."""

    model: Literal["carreau_yasuda"] = "carreau_yasuda"
    mu_0: float = positive(0.056, " (Pa s)")
    mu_inf: float = positive(0.00345, " (Pa s)")
    relaxation_time: float = positive(1.902, " (s)")
    power_index: float = positive(0.22)
    yasuda_exponent: float = positive(1.25)


@dataclass(frozen=True)
class Cross(PlateauLaw):
    """μ(s) = μ∞ + (μ0 − μ∞) / (1 + (λ s)^m). Defaults: blood (Johnston et al. 2004)."""

    model: Literal["cross"] = "cross"
    mu_0: float = positive(0.0364, " (Pa s)")
    mu_inf: float = positive(0.0035, " (Pa s)")
    relaxation_time: float = positive(0.38, " (s)")
    exponent: float = positive(1.45)


@dataclass(frozen=True)
class PowerLaw:
    """μ(s) = K (s² + s0²)^((n − 1)/2): the power law K s^(n−1) with the shear rate smoothly
    floored at s0, so μ(0) = K s0^(n−1) is finite. Defaults: blood, K and n of Johnston et al.
    (2004); s0 = 0.0169 1/s puts μ(0) at their cap of 0.056 Pa s."""

    model: Literal["power_law"] = "power_law"
    consistency: float = positive(0.017, " (Pa s^n)")
    power_index: float = positive(0.708)
    shear_rate_floor: float = positive(0.0169, " (1/s)")


@dataclass(frozen=True)
class Casson:
    """Casson's √τ = √τy + √(μc s), regularised after Papanastasiou:
    μ(s) = (√μc + √(τy / s) (1 − exp(−√(m s))))², finite at s = 0 (μ(0) = (√μc + √(τy m))²).
    Defaults: typical blood values (τy 5 mPa, μc 3.5 mPa s) and m = 100 s."""

    model: Literal["casson"] = "casson"
    viscosity: float = positive(0.0035, " (Pa s)")
    yield_stress: float = positive(0.005, " (Pa)")
    regularization: float = positive(100.0, " (s)")


Rheology = Newtonian | Carreau | CarreauYasuda | Cross | PowerLaw | Casson


@dataclass(frozen=True)
class InletPulse:
    """Inlet traction h(t) = (A/2)(1 − cos(2π t / T)) e_x for t ≤ T, 0 after (MODEL.md §2)."""

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
class TractionFreeOutlet:
    """σ n = 0 (in the ``open_boundary`` form; the study's outlet, the default). Every outlet's
    ``backflow_stabilization`` β ≥ 0 scales the term that removes the kinetic energy of blood
    re-entering through it (Bazilevs et al. 2009; docs/boundary-conditions.md)."""

    kind: Literal["traction_free"] = "traction_free"
    backflow_stabilization: float = non_negative(1.0)


@dataclass(frozen=True)
class ResistanceOutlet:
    """σ n = −P n with P = P_ref + R Q (in the ``open_boundary`` form): Q (m²/s) the flow rate
    per unit depth out through the outlet, ``resistance`` R (Pa s/m², per unit depth),
    ``reference_pressure`` P_ref (Pa). Q is the step's own (implicit:
    fsi.physics.fluid_residual.LumpedOutlet)."""

    kind: Literal["resistance"] = "resistance"
    resistance: float = non_negative(0.0, " (Pa s/m^2)")
    reference_pressure: float = 0.0
    backflow_stabilization: float = non_negative(1.0)


@dataclass(frozen=True)
class WindkesselOutlet:
    """The three-element Windkessel (RCR): σ n = −P n with P = P_c + R_p Q and
    C dP_c/dt = Q − (P_c − P_ref)/R_d, P_c(0) = P_0: ``proximal_resistance`` R_p and
    ``distal_resistance`` R_d (Pa s/m²), ``compliance`` C (m²/Pa), ``initial_pressure`` P_0 and
    ``reference_pressure`` P_ref (Pa); Q (m²/s) per unit depth as for :class:`ResistanceOutlet`.
    The ODE is integrated with the fluid's scheme (fsi/physics/outlets.py)."""

    kind: Literal["windkessel"] = "windkessel"
    proximal_resistance: float = non_negative(0.0, " (Pa s/m^2)")
    distal_resistance: float = positive(1.0e6, " (Pa s/m^2)")
    compliance: float = positive(1.0e-7, " (m^2/Pa)")
    initial_pressure: float = 0.0
    reference_pressure: float = 0.0
    backflow_stabilization: float = non_negative(1.0)


Outlet = TractionFreeOutlet | ResistanceOutlet | WindkesselOutlet


@dataclass(frozen=True)
class Fluid:
    """Blood (MODEL.md §2) and its open boundaries (docs/boundary-conditions.md compares the
    options; the defaults are the verified choice of the study's cases).

    ``open_boundary`` is the form of the inlet/outlet traction conditions: ``do_nothing``
    μ ∇u n − p n = −P n (Heywood, Rannacher & Turek 1996), exact for fully developed flow;
    ``stress`` σ n = −P n (σ the Cauchy stress), whose tangential part forbids fully developed
    flow. ``normal_flow``: the velocity on a traction inlet is normal to it (u·t = 0, strongly;
    the "normal flow" pressure inlet of commercial CFD codes) and only the normal traction is
    prescribed there, so the inlet keeps its static pressure P. ``inflow_stabilization`` β ≥ 0
    adds −β/2 ρ min(u·n, 0) u to a traction inlet's σ n: at an inlet, where all the flow is
    inflow, that lowers the pressure by β ρ (u·n)²/2, i.e. it makes the static-pressure inlet
    nearly a total-pressure one (0, the default, keeps the study's static pressure).
    ``supg``: streamline-upwind/Petrov–Galerkin stabilization of the momentum equation
    (Brooks & Hughes 1982; τ of Tezduyar & Osawa 2000), consistent: it adds a multiple of the
    strong residual, so an exact discrete solution (Poiseuille flow) is unchanged; for flows
    whose cell Reynolds number at the inlet is too high for the Galerkin form."""

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
