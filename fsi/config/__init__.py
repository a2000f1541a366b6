"""Typed, validated case configuration loaded from YAML.

A case is a tree of frozen dataclasses (:class:`Case`); the YAML file mirrors it key for key and
every key is optional (defaults are the study's values, ../shared/MODEL.md). Precedence: defaults
< YAML < ``--set key.path=value`` overrides. Unknown keys, wrong types and out-of-range values
raise :class:`ConfigError` naming the file, the key and what is expected, before anything is
computed. The schema is documented in docs/configuration.md.

What a configuration may not do (each refused with a :class:`ConfigError`): hold a number that
is not finite; break the file limits of :mod:`fsi.config.reader` (size, nesting, repeated keys);
give PETSc any option outside the allow-list of :mod:`fsi.config.petsc_options` (no viewers,
monitors, Python types, options files or file paths); ask for more than ``time.max_steps``
steps or, by :func:`fsi.config.run_size.estimated_cells`, more than ``mesh.max_cells`` triangles;
give an inlet formula the language of :mod:`fsi.config.boundary_data` refuses or one that fails at
t = 0 or at a step time of the schedule; give a ``pressure_file`` inlet whose CSV file cannot be
read or is not a waveform (:func:`fsi.config.boundary_data.read_waveform`).

Reading and building live in :mod:`fsi.config.reader`; this module is the schema (the
dataclasses and their defaults), the checks that involve several keys (:func:`validate`) and
the conversion back to YAML (:func:`to_dict`).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml

from fsi.config.boundary_data import (
    FORMULA_NAMES,
    FormulaError,
    WaveformError,
    read_waveform,
    time_function,
)
from fsi.config.petsc_options import check_petsc_options
from fsi.config.reader import (
    ConfigError,
    apply_overrides,
    at_least,
    build,
    checked,
    non_negative,
    open_interval,
    positive,
    read_case_file,
)
from fsi.config.run_size import BYTES_PER_CELL, count_steps, estimated_cells, format_count
from fsi.numerics.timestepping import steps
from geometry import stenosis as stenosis_geometry

# --------------------------------------------------------------------------------------------
# Geometry and mesh


@dataclass(frozen=True)
class StenosisGeometry:
    """The stenosed carotid of MODEL.md §1 (geometry/stenosis.py has the profiles)."""

    kind: Literal["stenosis"] = "stenosis"
    length: float = positive(0.02, " (m)")
    height: float = positive(0.007, " (m)")
    wall_thickness: float = positive(0.001, " (m)")
    stenosis_length: float = positive(0.01, " (m)")
    stenosis_degree: float = open_interval(0.5, 0.0, 1.0)
    cap_thickness: float = positive(0.0005, " (m)")
    lipid_length: float = positive(0.006, " (m)")
    plaque_sides: tuple[Literal["bottom", "top"], ...] = ("bottom",)


@dataclass(frozen=True)
class ChannelGeometry:
    """A straight rigid channel for verification cases (geometry/channel.py)."""

    kind: Literal["channel"] = "channel"
    length: float = positive(0.02, " (m)")
    height: float = positive(0.007, " (m)")


@dataclass(frozen=True)
class TurekHronGeometry:
    """The Turek–Hron benchmark (../shared/reference/turek_hron.md, geometry/turek_hron.py): a
    channel ``[0, length] × [0, height]``, a rigid cylinder and an elastic flag of
    ``flag_length`` (from the cylinder's rightmost point to the tip) × ``flag_thickness`` centred
    on the cylinder's axis. Defaults are the benchmark's (tip and point A at x = 0.6)."""

    kind: Literal["turek_hron"] = "turek_hron"
    length: float = positive(2.5, " (m)")
    height: float = positive(0.41, " (m)")
    cylinder_centre: tuple[float, ...] = (0.2, 0.2)
    cylinder_radius: float = positive(0.05, " (m)")
    flag_length: float = positive(0.35, " (m)")
    flag_thickness: float = positive(0.02, " (m)")


MESH_LEVELS = {"coarse": 0, "medium": 1, "fine": 2, "finest": 3}


@dataclass(frozen=True)
class MeshSettings:
    """gmsh sizes of the coarse mesh: ``size`` away from, ``local_size`` at the plaque (or the
    obstacle); ``level`` adds uniform refinements (medium = coarse × 4, fine = coarse × 16,
    finest = coarse × 64: the third level of the performance study, docs/performance.md).

    ``max_cells``: validation refuses a mesh whose :func:`estimated_cells` exceeds it, before
    gmsh starts (memory grows with the cells: the fine stenosis, 51k triangles, took ~0.9 GB
    in a serial coupled run, ~18 kB per triangle, so the default 10⁶ is ~18 GB)."""

    level: Literal["coarse", "medium", "fine", "finest"] = "coarse"
    size: float = positive(6.0e-4, " (m)")
    local_size: float = positive(2.2e-4, " (m)")
    max_cells: int = at_least(1_000_000, 1)

    @property
    def refinements(self) -> int:
        return MESH_LEVELS[self.level]


def quadrature(default: int) -> Any:
    """A quadrature degree in [1, :data:`MAX_QUADRATURE_DEGREE`]."""
    return checked(
        default,
        lambda v: 1 <= v <= MAX_QUADRATURE_DEGREE,
        f"an integer in [1, {MAX_QUADRATURE_DEGREE}]",
    )


MAX_QUADRATURE_DEGREE = 20
"""The highest quadrature degree a case may set. The shipped cases use 4 (exact for the P2 SVK
residual); a triangle rule of degree q has about (q/2 + 1)² points, which the form compiler
unrolls into the generated C and assembly visits in every cell, so cost grows as q² (UFL's own
choice of 22 for the Carreau Jacobian assembled 5× slower than 4, DESIGN.md) and degree 100000
never finishes compiling (issue #14). 20 leaves room for convergence studies."""


# --------------------------------------------------------------------------------------------
# Fluid


@dataclass(frozen=True)
class Newtonian:
    model: Literal["newtonian"] = "newtonian"
    viscosity: float = positive(0.0035, " (Pa s)")


@dataclass(frozen=True)
class Carreau:
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)²)^((n − 1)/2)."""

    model: Literal["carreau"] = "carreau"
    mu_0: float = positive(0.0456, " (Pa s)")
    mu_inf: float = positive(0.0032, " (Pa s)")
    relaxation_time: float = positive(10.03, " (s)")
    power_index: float = positive(0.344)


@dataclass(frozen=True)
class CarreauYasuda:
    """μ(s) = μ∞ + (μ0 − μ∞)(1 + (λ s)^a)^((n − 1)/a). Defaults: blood (Cho & Kensey 1991, as
    used by Johnston et al. 2004)."""

    model: Literal["carreau_yasuda"] = "carreau_yasuda"
    mu_0: float = positive(0.056, " (Pa s)")
    mu_inf: float = positive(0.00345, " (Pa s)")
    relaxation_time: float = positive(1.902, " (s)")
    power_index: float = positive(0.22)
    yasuda_exponent: float = positive(1.25)


@dataclass(frozen=True)
class Cross:
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
    """True, or :class:`FormulaError` saying why ``text`` is not an allowed formula."""
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
    rows must cover [0, T] (checked by :func:`validate`)."""

    kind: Literal["pressure_table"] = "pressure_table"
    table: tuple[tuple[float, ...], ...] = checked(
        ((0.0, 0.0),), _is_time_table, "a non-empty list of [t, P] pairs with increasing t"
    )
    period: float = _period()


@dataclass(frozen=True)
class InletPressureFile:
    """A :class:`InletPressureTable` whose rows come from the CSV file ``file`` (relative to
    the case file's folder; to the current directory when ``--set`` gives it), read once by
    :func:`from_dict` into ``table`` (:func:`read_waveform` says what the file may hold).
    :func:`to_dict` writes it as a ``pressure_table`` of those rows, so a run's config.yaml
    does not need the file."""

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
    fsi.physics.fluid.LumpedOutlet)."""

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
class SolverSettings:
    """Newton tolerances and the PETSc options of one sub-solver (its prefix is fixed).

    ``jacobian_reuse``: ``none`` assembles (and factorises) the Jacobian at every Newton
    iteration; ``step`` keeps the last one across the Newton and coupling iterations of a time
    step, ``run`` also across steps, while it still contracts the residual: it is re-assembled
    when ``|F(x_k)| > jacobian_reuse_rate · |F(x_{k−1})|`` (modified Newton,
    fsi/numerics/newton.py). The stopping test is unchanged, so is the converged answer (to the
    solver's tolerance); a failed solve with a reused Jacobian is repeated with fresh ones. ``step``
    keeps restarts exact (the path of a step depends only on the state at its start)."""

    rtol: float = positive(1.0e-9)
    atol: float = positive(1.0e-10)
    max_iterations: int = at_least(25, 1)
    jacobian_reuse: Literal["none", "step", "run"] = "none"
    jacobian_reuse_rate: float = open_interval(0.3, 0.0, 1.0)
    # Names and values are checked against an allow-list (check_petsc_options) in validate().
    petsc_options: dict[str, str | int | float] = field(
        default_factory=lambda: {
            "ksp_type": "preonly",
            "pc_type": "lu",
            "pc_factor_mat_solver_type": "mumps",
        }
    )


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


# --------------------------------------------------------------------------------------------
# Structure


@dataclass(frozen=True)
class Material:
    """Hyperelastic material of one structure region (MODEL.md §3; fsi/physics/materials.py): the
    study's St. Venant–Kirchhoff ``svk`` or a compressible ``neo_hookean``, plane strain.
    ``viscous_relaxation_time`` τ (s) adds the Kelvin–Voigt viscous stress
    ``S_v = τ (λ tr Ė I + 2μ Ė)`` (docs/wall-damping.md): every small-amplitude mode of
    angular frequency ω gets the damping ratio ζ = ωτ/2; 0 (the default) is purely elastic."""

    law: Literal["svk", "neo_hookean"] = "svk"
    density: float = positive(1200.0, " (kg/m^3)")
    young_modulus: float = positive(1.6e6, " (Pa)")
    poisson_ratio: float = open_interval(0.45, -1.0, 0.5)
    viscous_relaxation_time: float = non_negative(0.0, " (s)")


@dataclass(frozen=True)
class WallMaterial(Material):
    """The vessel wall's defaults (E = 4 MPa); keys not given keep these, not the plaque's."""

    young_modulus: float = positive(4.0e6, " (Pa)")


@dataclass(frozen=True)
class FlagMaterial(Material):
    """The Turek–Hron flag's defaults (CSM1/FSI1: ρ 1000, μs 0.5 MPa → E 1.4 MPa, ν 0.4)."""

    density: float = positive(1000.0, " (kg/m^3)")
    young_modulus: float = positive(1.4e6, " (Pa)")
    poisson_ratio: float = open_interval(0.4, -1.0, 0.5)


@dataclass(frozen=True)
class GeneralizedAlpha:
    """Chung–Hulbert generalized-α with high-frequency spectral radius ρ∞ (1: no dissipation,
    0: asymptotic annihilation). The study does not state its scheme; a dissipative default
    damps the structure's unresolved modes (their periods are far below the 5 ms step)."""

    scheme: Literal["generalized_alpha"] = "generalized_alpha"
    spectral_radius: float = checked(0.5, lambda v: 0 <= v <= 1, "a number in [0, 1]")


@dataclass(frozen=True)
class Newmark:
    """The trapezoidal rule (β = 1/4, γ = 1/2): no numerical dissipation, energy-conserving."""

    scheme: Literal["newmark"] = "newmark"


@dataclass(frozen=True)
class QuasiStatic:
    """No inertia: the structure is in equilibrium with its loads at every step."""

    scheme: Literal["quasi_static"] = "quasi_static"


StructuralTimeIntegration = GeneralizedAlpha | Newmark | QuasiStatic


@dataclass(frozen=True)
class TissueSupport:
    """The surrounding tissue as a spring–dashpot on the wall's exterior ΓN (Moireau et al.
    2012; docs/wall-damping.md), normal direction only: ``P N = −(k_s η·N + c_s η̇·N) N``
    per unit reference length, with ``stiffness`` k_s (Pa/m) and ``damping`` c_s (Pa·s/m).
    0 and 0 (the defaults): a traction-free exterior. Acts where ΓN is free (``moving_wall``;
    inert in ``fixed_wall``, where the wall is held); the Turek–Hron flag has no ΓN and
    ignores it (with a warning)."""

    stiffness: float = non_negative(0.0, " (Pa/m)")
    damping: float = non_negative(0.0, " (Pa s/m)")


@dataclass(frozen=True)
class Structure:
    """``fixed_wall``: vessel wall held, plaque deforms; ``moving_wall``: wall and plaque deform
    (clamped at the wall ends; the Turek–Hron flag at its joint with the cylinder); ``rigid``: no
    structure solve (fluid-only runs). ``flag`` is the Turek–Hron flag's material (CSM1/FSI1
    values by default); ``support`` the surrounding tissue on the stenosis wall's exterior ΓN
    (:class:`TissueSupport`; ignored by the Turek–Hron flag, which has no ΓN);
    ``body_force`` a force per unit mass on the structure (gravity, m/s²);
    ``degree`` the Lagrange degree of the displacement (P1 locks in bending).
    ``interface_load``: ``fluid`` couples the structure to the blood; ``inlet_pressure`` solves
    the structure alone under the follower pressure P(t) of ``fluid.inlet`` on the interface
    (no fluid solve); ``none`` solves it alone under ``body_force`` only (Turek–Hron CSM)."""

    mode: Literal["fixed_wall", "moving_wall", "rigid"] = "fixed_wall"
    interface_load: Literal["fluid", "inlet_pressure", "none"] = "fluid"
    wall: WallMaterial = field(default_factory=WallMaterial)
    cap: Material = field(default_factory=Material)
    lipid: Material = field(default_factory=Material)
    flag: FlagMaterial = field(default_factory=FlagMaterial)
    support: TissueSupport = field(default_factory=TissueSupport)
    body_force: tuple[float, ...] = checked(
        (0.0, 0.0), lambda v: len(v) == 2, "a list of two numbers [gx, gy] (m/s^2)"
    )
    time_integration: StructuralTimeIntegration = field(default_factory=GeneralizedAlpha)
    degree: int = checked(2, lambda v: 1 <= v <= 3, "an integer in [1, 3]")
    quadrature_degree: int = quadrature(4)
    solver: SolverSettings = field(default_factory=SolverSettings)


# --------------------------------------------------------------------------------------------
# Time, coupling, output


@dataclass(frozen=True)
class TimeSegment:
    """Steps of ``dt`` until time ``until`` (the last step of a segment ends exactly on it)."""

    until: float = positive(0.4, " (s)")
    dt: float = positive(5.0e-3, " (s)")


MAX_CYCLES = 1000
"""The most heartbeats ``time.cycles`` may ask for (each repeats the schedule's segments)."""


@dataclass(frozen=True)
class Time:
    """The step schedule; the default is the study's: 5 ms to 0.4 s, then 10 ms to 0.8 s.

    ``scheme``: the fluid's time scheme. ``steady`` drops ∂u/∂t and the mesh velocity: every
    step solves the steady equations with the boundary data at its time (a continuation through
    an inflow ramp); with a ``quasi_static`` structure a coupled step is a steady FSI solve.

    ``retries``: how often a step whose solve fails is taken again as two steps of half its
    size, from the state before it (each half may be halved again while retries remain: up to
    2^retries substeps); the metrics row is the scheduled step's. 0: a failed step ends the run.

    ``max_steps``: validation refuses a schedule of more steps to ``end`` (:func:`count_steps`),
    so a mistyped ``dt`` fails at once instead of running for ever.

    ``cycles``: N >= 1 runs N heartbeats of the inlet's ``period`` T (``fluid.inlet.period``),
    to t = N T. ``schedule`` is then one heartbeat's: its steps from 0 to T are repeated in
    every heartbeat (:meth:`run_schedule`), and ``end`` must be T (one heartbeat, as a case
    file for one beat has it) or N T (the whole run); :func:`validate` refuses anything else,
    and N > 1 without a period. 0 (the default): ``end`` and ``schedule`` as written.
    """

    end: float = positive(0.8, " (s)")
    scheme: Literal["backward_euler", "bdf2", "steady"] = "bdf2"
    schedule: tuple[TimeSegment, ...] = (TimeSegment(0.4, 5.0e-3), TimeSegment(0.8, 1.0e-2))
    retries: int = checked(0, lambda v: 0 <= v <= 8, "an integer in [0, 8]")
    max_steps: int = at_least(1_000_000, 1)
    cycles: int = checked(
        0,
        lambda v: 0 <= v <= MAX_CYCLES,
        f"an integer in [0, {MAX_CYCLES}] (0: time.end sets the end)",
    )

    def run_schedule(self, period: float) -> Time:
        """The schedule the run steps through (:func:`fsi.numerics.timestepping.steps` of it): this
        one when ``cycles`` is 0 or there is no ``period``; else ``cycles`` copies of this
        schedule's steps from 0 to ``period`` T, the k-th shifted by (k − 1) T so that every
        heartbeat ends exactly on k T, and ``end`` = ``cycles`` × T."""
        if self.cycles < 1 or not period > 0:
            return self
        beat = []  # one heartbeat's segments: (until within (0, T], dt)
        for segment in self.schedule:
            beat.append((min(segment.until, period), segment.dt))
            if segment.until >= period:
                break
        segments = []
        for k in range(self.cycles):
            for until, dt in beat:
                end_of_beat = until >= period
                segments.append(
                    TimeSegment((k + 1) * period if end_of_beat else k * period + until, dt)
                )
        return dataclasses.replace(
            self, end=self.cycles * period, schedule=tuple(segments), cycles=0
        )


@dataclass(frozen=True)
class Coupling:
    """Dirichlet–Neumann iterations per step (MODEL.md §5; fsi/coupled/coupling.py).

    ``initial_relaxation``: ω of constant relaxation, Aitken's first ω and IQN-ILS's relaxed
    first iteration; ``max_relaxation``: Aitken's cap |ω| <= ω_max; ``iqn_reuse``: time steps
    whose secant columns IQN-ILS reuses; ``iqn_filter``: its QR filter threshold (relative);
    ``predictor``: extrapolation of the interface displacement from previous steps.
    """

    acceleration: Literal["constant", "aitken", "iqn-ils"] = "aitken"
    tolerance: float = positive(1.0e-6)
    max_iterations: int = at_least(50, 1)
    initial_relaxation: float = checked(0.5, lambda v: 0 < v <= 1, "a number in (0, 1]")
    max_relaxation: float = positive(1.0)
    iqn_reuse: int = at_least(4, 0)
    iqn_filter: float = positive(1.0e-2)  # 1e-8 kept stale columns: IQN diverged on the stenosis
    predictor: Literal["constant", "linear", "quadratic"] = "linear"


@dataclass(frozen=True)
class MeshMotion:
    """ALE extension of the interface displacement into the fluid (MODEL.md §5;
    fsi/physics/mesh_motion.py): ``harmonic`` −∇·(k ∇d) = 0, ``elastic`` −∇·(k σ(d)) = 0 with
    σ = 2 ε + λ' tr(ε) I, λ' = 2ν/(1 − 2ν) from ``poisson_ratio``, or ``biharmonic`` Δ²d = 0
    (the minimiser of ∫ k |∇∇d|², mixed with the Hessian as auxiliary field; natural condition
    ∂²d/∂n² = 0 where d is given, so affine motions are extended exactly). Stiffening k (per cell):
    ``none`` k = 1; ``jacobian`` k = (J_max/J)^e with J the reference cell area (small cells
    stiffer); ``distance`` k = (δ_max/δ)^e with δ the centroid's distance to the moving boundary;
    e = ``stiffening_exponent``. ``min_jacobian_ratio``: the quality guard stops when a cell's
    area falls below this fraction of its reference area (or the cell inverts).
    ``petsc_options``: the linear solver's options (prefix ``mesh_``)."""

    method: Literal["harmonic", "elastic", "biharmonic"] = "harmonic"
    stiffening: Literal["none", "jacobian", "distance"] = "jacobian"
    stiffening_exponent: float = non_negative(1.0)
    poisson_ratio: float = open_interval(0.3, -1.0, 0.5)
    min_jacobian_ratio: float = open_interval(0.05, 0.0, 1.0)
    petsc_options: dict[str, str | int | float] = field(
        default_factory=lambda: {
            "ksp_type": "preonly",
            "pc_type": "lu",
            "pc_factor_mat_solver_type": "mumps",
        }
    )


@dataclass(frozen=True)
class Output:
    # XDMF only: Debian 12's dolfinx has no ADIOS2 (no VTX), and 0.9's VTX writer takes one
    # element per file, where a run writes P1 and per-cell fields side by side.
    fields: Literal["xdmf"] = "xdmf"
    fields_every: int = at_least(1, 1)
    checkpoint_every: int = at_least(10, 1)
    report_times: tuple[float, ...] = checked(
        (0.01, 0.02, 0.05, 0.1, 0.8), lambda v: all(t >= 0 for t in v), "a list of times >= 0 (s)"
    )


@dataclass(frozen=True)
class Case:
    name: str = "case"
    geometry: StenosisGeometry | ChannelGeometry | TurekHronGeometry = field(
        default_factory=StenosisGeometry
    )
    mesh: MeshSettings = field(default_factory=MeshSettings)
    fluid: Fluid = field(default_factory=Fluid)
    structure: Structure = field(default_factory=Structure)
    time: Time = field(default_factory=Time)
    coupling: Coupling = field(default_factory=Coupling)
    mesh_motion: MeshMotion = field(default_factory=MeshMotion)
    output: Output = field(default_factory=Output)


# --------------------------------------------------------------------------------------------
# Loading


def load(path: str | Path, overrides: typing.Sequence[str] = ()) -> Case:
    """Read a case from YAML, apply ``key.path=value`` overrides, build and validate it.

    Every failure is a :class:`ConfigError` naming the file (or ``--set``) and the key: what
    :func:`fsi.config.reader.read_case_file` refuses (unreadable, too large, not UTF-8, invalid
    or too deeply nested YAML, a repeated key) and whatever :func:`from_dict` refuses.
    """
    data = read_case_file(path)
    overridden = apply_overrides(data, overrides)
    return from_dict(data, str(path), overridden)


def from_dict(data: dict, source: str = "<dict>", overridden: set[str] | None = None) -> Case:
    """Build and validate a :class:`Case` from a plain dict (as read from YAML).

    ``overridden``: the keys :func:`apply_overrides` set (and the sections it created); an
    error at one of them, below one (``time.schedule[0].dt`` below ``time.schedule``) or about
    a whole section one changed (``mesh``'s cell count after ``--set mesh.size=...``) names
    ``--set`` instead of ``source``."""
    overridden = overridden or set()
    try:
        case = build(Case, data, "")
        case = _read_inlet_file(case, source, overridden)
        validate(case)
    except ConfigError as e:
        from_command_line = any(
            e.key == k or e.key.startswith((k + ".", k + "[")) or k.startswith(e.key + ".")
            for k in overridden
        )
        raise e.from_source("--set" if from_command_line else source) from None
    return case


def heartbeat_period(case: Case) -> float:
    """The inlet's period T (s) when it repeats (a ``pressure_table`` or ``pressure_file``
    inlet with ``period`` > 0), else 0."""
    return float(getattr(case.fluid.inlet, "period", 0.0))


def run_time(case: Case) -> Time:
    """The schedule the run steps through: ``time`` itself, or with ``time.cycles`` and a
    periodic inlet the heartbeats one after another (:meth:`Time.run_schedule`), whose ``end``
    is cycles × period."""
    return case.time.run_schedule(heartbeat_period(case))


def validate(case: Case) -> None:
    """Checks that involve several keys (single values are checked while building), in the
    order of the sections: geometry, structure load, mesh size, schedule, solvers, inlet."""
    _validate_geometry(case)
    _validate_structure_load(case)
    _validate_cell_count(case)  # before the size order: mesh.size 1e-6 gets the estimate
    if case.mesh.local_size > case.mesh.size:
        raise ConfigError(
            "", "mesh.local_size", f"at most mesh.size = {case.mesh.size} m", case.mesh.local_size
        )
    _validate_schedule(case)
    _validate_solvers(case)
    check_petsc_options(case.fluid.solver.petsc_options, "fluid.solver.petsc_options")
    check_petsc_options(case.structure.solver.petsc_options, "structure.solver.petsc_options")
    check_petsc_options(case.mesh_motion.petsc_options, "mesh_motion.petsc_options")
    _validate_inlet(case)  # last: it walks the schedule, now known to be of bounded length


def _validate_geometry(case: Case) -> None:
    g = case.geometry
    if isinstance(g, StenosisGeometry):
        _validate_stenosis(g)
    elif isinstance(g, TurekHronGeometry):
        # Any structure mode: 'rigid' is the CFD benchmark, the others make the flag elastic.
        _validate_turek_hron(g)
    elif case.structure.mode != "rigid":
        raise ConfigError(
            "",
            "structure.mode",
            f"'rigid' for geometry.kind '{g.kind}' (it has no structure)",
            case.structure.mode,
        )


def _validate_stenosis(g: StenosisGeometry) -> None:
    """Plaque sides once each; the stenosis inside the segment; the cap thinner than the
    plaque and nowhere thinner than ``cap_thickness`` over the lipid pool."""
    if len(set(g.plaque_sides)) != len(g.plaque_sides) or not g.plaque_sides:
        raise ConfigError(
            "", "geometry.plaque_sides", "'bottom', 'top' or both, once each", list(g.plaque_sides)
        )
    if g.stenosis_length >= g.length:
        raise ConfigError(
            "",
            "geometry.stenosis_length",
            f"less than geometry.length = {g.length} m",
            g.stenosis_length,
        )
    plaque = stenosis_geometry.plaque_height(g)
    if g.cap_thickness >= plaque:
        raise ConfigError(
            "",
            "geometry.cap_thickness",
            f"less than the plaque height {plaque:g} m (stenosis_degree × height / plaque sides)",
            g.cap_thickness,
        )
    if g.lipid_length >= g.stenosis_length:
        raise ConfigError(
            "",
            "geometry.lipid_length",
            f"less than geometry.stenosis_length = {g.stenosis_length} m",
            g.lipid_length,
        )
    thinnest = stenosis_geometry.min_cap_thickness(g)
    if thinnest < g.cap_thickness * (1 - 1e-4):
        raise ConfigError(
            "",
            "geometry.lipid_length",
            "a lipid pool short enough that the fibrous cap is nowhere thinner"
            f" than cap_thickness = {g.cap_thickness} m (it would be"
            f" {thinnest:.3g} m)",
            g.lipid_length,
        )


def _validate_structure_load(case: Case) -> None:
    if case.structure.interface_load != "fluid":
        if case.structure.mode == "rigid":
            raise ConfigError(
                "",
                "structure.interface_load",
                "'fluid' when structure.mode is 'rigid' (there is no structure to load)",
                case.structure.interface_load,
            )
        if case.structure.interface_load == "inlet_pressure" and isinstance(
            case.fluid.inlet, ParabolicInflow
        ):
            raise ConfigError(
                "",
                "structure.interface_load",
                "'fluid' or 'none' with a velocity inlet ('inlet_pressure' needs a traction inlet)",
                case.structure.interface_load,
            )


def _validate_schedule(case: Case) -> None:
    """Segments in increasing order covering the run (one heartbeat's with ``time.cycles``),
    and at most ``time.max_steps`` steps."""
    schedule = case.time.schedule
    if not schedule:
        raise ConfigError("", "time.schedule", "at least one {until, dt} segment", [])
    for i in range(1, len(schedule)):
        if schedule[i].until <= schedule[i - 1].until:
            raise ConfigError(
                "",
                f"time.schedule[{i}].until",
                f"greater than time.schedule[{i - 1}].until = {schedule[i - 1].until} s",
                schedule[i].until,
            )
    period = heartbeat_period(case)
    _validate_cycles(case.time, period)
    if case.time.cycles >= 1 and period > 0:  # the schedule is one heartbeat's
        if schedule[-1].until < period * (1 - 1e-12):
            raise ConfigError(
                "",
                f"time.schedule[{len(schedule) - 1}].until",
                f"at least fluid.inlet.period = {period} s (with time.cycles the "
                "schedule is one heartbeat's)",
                schedule[-1].until,
            )
    elif schedule[-1].until < case.time.end * (1 - 1e-12):
        raise ConfigError(
            "",
            f"time.schedule[{len(schedule) - 1}].until",
            f"at least time.end = {case.time.end} s",
            schedule[-1].until,
        )
    run = run_time(case)
    count = count_steps(run)
    if count > case.time.max_steps:
        raise_limit = (
            f"raise the limit (--set time.max_steps={int(count)}) if you mean it"
            if math.isfinite(count)
            else "no limit can be that high"
        )
        to = (
            f"time.end = {case.time.end:g} s"
            if run is case.time
            else f"the end of time.cycles = {case.time.cycles} heartbeats, {run.end:g} s"
        )
        raise ConfigError(
            "",
            "time.schedule",
            reason=(
                f"{format_count(count)} steps to {to}, more than "
                f"time.max_steps = {case.time.max_steps:,}: use larger dt, or {raise_limit}"
            ),
        )


def _validate_solvers(case: Case) -> None:
    if (
        case.time.scheme == "steady"
        and case.structure.mode != "rigid"
        and case.structure.time_integration.scheme != "quasi_static"
    ):
        raise ConfigError(
            "",
            "structure.time_integration.scheme",
            "'quasi_static' when "
            "time.scheme is 'steady' (a steady fluid cannot load a structure "
            "with inertia)",
            case.structure.time_integration.scheme,
        )

    if case.coupling.max_relaxation < case.coupling.initial_relaxation:
        raise ConfigError(
            "",
            "coupling.max_relaxation",
            f"at least coupling.initial_relaxation = {case.coupling.initial_relaxation}",
            case.coupling.max_relaxation,
        )

    # Sub-solvers must be well below the coupling tolerance or the coupling stalls near it.
    for name in ("fluid", "structure"):
        rtol = getattr(case, name).solver.rtol
        if rtol > case.coupling.tolerance / 10:
            raise ConfigError(
                "",
                f"{name}.solver.rtol",
                f"at most coupling.tolerance / 10 = {case.coupling.tolerance / 10:g}",
                rtol,
            )


def _validate_cell_count(case: Case) -> None:
    """Refuse a mesh whose :func:`estimated_cells` exceeds ``mesh.max_cells``, before gmsh."""
    cells = estimated_cells(case)
    if cells > case.mesh.max_cells:
        m = case.mesh
        gigabytes = cells * BYTES_PER_CELL / 1e9
        memory = (
            f"{gigabytes:.2g} GB"
            if gigabytes < 10
            else f"{gigabytes:,.0f} GB"
            if gigabytes < 1e9
            else "too much"
        )
        raise ConfigError(
            "",
            "mesh",
            reason=(
                f"{format_count(cells)} triangles estimated (mesh.size = {m.size:g} m, "
                f"mesh.local_size = {m.local_size:g} m, mesh.level = {m.level}), more than "
                f"mesh.max_cells = {m.max_cells:,} (a coupled run needs "
                f"~{BYTES_PER_CELL / 1e3:.0f} kB per triangle: {memory}): use larger sizes or a "
                "coarser level, or raise mesh.max_cells if you "
                "mean it"
            ),
        )


def _validate_cycles(time: Time, period: float) -> None:
    """``time.cycles`` N > 1 needs an inlet ``period`` T > 0; with N >= 1 and T, ``time.end``
    is one heartbeat (T) or the whole run (N T), within 1e-9 relative (:class:`Time`)."""
    n = time.cycles
    if n > 1 and not period > 0:
        raise ConfigError(
            "",
            "time.cycles",
            reason=(
                f"{n} heartbeats need a periodic inlet (a pressure_table or pressure_file "
                "fluid.inlet with period > 0); this inlet does not repeat: use time.end instead"
            ),
        )
    if n >= 1 and period > 0:
        whole = n * period
        if not any(abs(time.end - t) <= 1e-9 * t for t in (period, whole)):
            raise ConfigError(
                "",
                "time.end",
                f"fluid.inlet.period = {period:g} s (one "
                f"heartbeat) or time.cycles × period = {whole:g} s (the whole "
                f"run) when time.cycles is {n}",
                time.end,
            )


def _validate_inlet(case: Case) -> None:
    """Evaluate an inlet formula at t = 0 and at every step time of the schedule: one that
    fails (division by zero, log(0), overflow, ...) is refused now, not mid-run."""
    inlet = case.fluid.inlet
    if isinstance(inlet, (InletPressureTable, InletPressureFile)):
        _validate_period(inlet)
    if not isinstance(inlet, InletPressure):
        return  # the pulse is closed-form; a table holds finite numbers and interpolates
    pressure = time_function(inlet.formula)
    try:
        pressure(0.0)
        for step in steps(case.time):
            pressure(step.t)
    except FormulaError as e:
        raise ConfigError(
            "", "fluid.inlet.formula", reason=f"evaluation fails at t = {e.t:.6g} s ({e.reason})"
        ) from None


def _validate_turek_hron(g: TurekHronGeometry) -> None:
    """The cylinder inside the channel, the flag attached to it and ending inside the channel."""
    if len(g.cylinder_centre) != 2:
        raise ConfigError(
            "",
            "geometry.cylinder_centre",
            "a list of two numbers [x, y] (m)",
            list(g.cylinder_centre),
        )
    cx, cy = g.cylinder_centre
    r = g.cylinder_radius
    if not (r < cx and r < cy < g.height - r):
        raise ConfigError(
            "",
            "geometry.cylinder_radius",
            f"a cylinder of centre {list(g.cylinder_centre)} inside the channel"
            f" [0, {g.length}] x [0, {g.height}] m",
            r,
        )
    if g.flag_thickness >= 2 * r:
        raise ConfigError(
            "",
            "geometry.flag_thickness",
            f"less than the cylinder diameter {2 * r} m",
            g.flag_thickness,
        )
    if cx + r + g.flag_length >= g.length:
        raise ConfigError(
            "",
            "geometry.flag_length",
            f"a flag tip (x = centre + radius + length) before the outlet x = {g.length} m",
            g.flag_length,
        )


def to_dict(case: Case) -> dict:
    """The resolved configuration as plain YAML-ready data (tuples as lists); a
    ``pressure_file`` inlet as the ``pressure_table`` of its rows and period, so that
    :func:`load` of the data needs no CSV file and gives the same P(t)."""

    def plain(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: plain(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [plain(x) for x in v]
        return v

    data = plain(dataclasses.asdict(case))
    inlet = case.fluid.inlet
    if isinstance(inlet, InletPressureFile):  # self-contained: the rows, not the file
        data["fluid"]["inlet"] = plain(
            dataclasses.asdict(InletPressureTable(table=inlet.table, period=inlet.period))
        )
    return data


def to_yaml(case: Case) -> str:
    """The resolved configuration as YAML text (``fsi run`` writes it as DIR/config.yaml)."""
    return yaml.safe_dump(to_dict(case), sort_keys=False)


def dump(case: Case, path: str | Path) -> None:
    Path(path).write_text(to_yaml(case))


def _read_inlet_file(case: Case, source: str, overridden: set[str]) -> Case:
    """``case`` with a ``pressure_file`` inlet's rows read into its ``table`` (other inlets
    unchanged). ``file`` is relative to the folder of ``source`` (the case file), or to the
    current directory when ``--set`` gave it (or ``source`` is not a file: ``<dict>``); the
    path kept in the case is the one opened."""
    inlet = case.fluid.inlet
    if not isinstance(inlet, InletPressureFile):
        return case
    if inlet.table:
        raise ConfigError(
            "",
            "fluid.inlet.table",
            reason="not a key of kind 'pressure_file' "
            "(its rows come from fluid.inlet.file; use kind 'pressure_table' to "
            "give them inline)",
        )
    if not inlet.file:
        raise ConfigError(
            "",
            "fluid.inlet.file",
            "the name of a CSV file of rows t, P (relative to the case file's folder)",
        )
    from_command_line = bool({"fluid", "fluid.inlet", "fluid.inlet.file"} & overridden)
    path = Path(inlet.file)
    if not path.is_absolute() and not from_command_line and source not in ("<dict>", "--set"):
        path = Path(source).parent / path
    try:
        rows = read_waveform(path)
    except OSError as e:
        raise ConfigError(
            "", "fluid.inlet.file", reason=f"cannot read {path} ({e.strerror or type(e).__name__})"
        ) from None
    except WaveformError as e:
        raise ConfigError("", "fluid.inlet.file", reason=str(e)) from None
    inlet = dataclasses.replace(inlet, file=str(path), table=rows)
    return dataclasses.replace(case, fluid=dataclasses.replace(case.fluid, inlet=inlet))


def _validate_period(inlet: InletPressureTable | InletPressureFile) -> None:
    """A periodic table must cover one period: first t <= 0 and last t >= period."""
    period = inlet.period
    first, last = inlet.table[0][0], inlet.table[-1][0]
    if period > 0 and not (first <= 0 <= period <= last):
        rows = (
            f"the rows of {inlet.file}"
            if isinstance(inlet, InletPressureFile)
            else "fluid.inlet.table"
        )
        raise ConfigError(
            "",
            "fluid.inlet.period",
            reason=(
                f"{rows} cover t in [{first:g}, {last:g}] s, not the whole period "
                f"[0, {period:g}] s (the first t must be <= 0 and the last >= period)"
            ),
        )
