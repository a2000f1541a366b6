"""The ``structure`` section of a case: which structure is solved and how (:class:`Structure`),
the material of each region (:class:`Material`; the laws are in :mod:`fsi.physics.materials`),
the time scheme (``time_integration.scheme`` picks a :data:`StructuralTimeIntegration`) and the
surrounding tissue (:class:`TissueSupport`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from fsi.config.reader import at_least, checked, non_negative, open_interval, positive
from fsi.config.solver_settings import SolverSettings, quadrature


@dataclass(frozen=True)
class Fibres:
    """The collagen fibres of an ``hgo`` material (Holzapfel, Gasser & Ogden 2000; Gasser,
    Ogden & Holzapfel 2006; fsi/physics/materials.py): two families at ±``angle`` degrees from
    the circumferential direction in the circumferential–axial plane, stiffness ``k1`` (Pa) and
    exponent ``k2`` (dimensionless), ``dispersion`` κ (0: every fibre along its family's mean
    direction; 1/3: isotropic)."""

    k1: float = non_negative(2.3632e3, "Pa")
    k2: float = positive(0.8393)
    angle: float = checked(29.0, lambda v: 0 <= v <= 90, "a number in [0, 90]", "degrees")
    dispersion: float = checked(0.0, lambda v: 0 <= v <= 1 / 3, "a number in [0, 1/3]")


@dataclass(frozen=True)
class Material:
    """Hyperelastic material of one structure region (docs/model.md §3;
    fsi/physics/materials.py): the study's St. Venant–Kirchhoff ``svk`` or a compressible
    ``neo_hookean``, plane strain.
    ``viscous_relaxation_time`` τ (s) adds the Kelvin–Voigt viscous stress
    ``S_v = τ (λ tr Ė I + 2μ Ė)`` (docs/wall-damping.md): every small-amplitude mode of
    angular frequency ω gets the damping ratio ζ = ωτ/2; 0 (the default) is purely elastic.
    ``hgo``: the fibre-reinforced arterial wall (docs/arterial-wall.md), whose ground matrix
    has the shear modulus ``c = E/(2(1 + ν))`` and the bulk modulus ``K = E/(3(1 − 2ν))`` of
    ``young_modulus`` and ``poisson_ratio``, and whose ``fibres`` (:class:`Fibres`, required
    with ``hgo`` and refused otherwise) stiffen it in stretch; axisymmetric cases only."""

    law: Literal["svk", "neo_hookean", "hgo"] = "svk"
    density: float = positive(1200.0, "kg/m^3")
    young_modulus: float = positive(1.6e6, "Pa")
    poisson_ratio: float = open_interval(0.45, -1.0, 0.5)
    viscous_relaxation_time: float = non_negative(0.0, "s")
    fibres: Fibres | None = None


@dataclass(frozen=True)
class WallMaterial(Material):
    """The vessel wall's defaults (E = 4 MPa); keys not given keep these, not the plaque's."""

    young_modulus: float = positive(4.0e6, "Pa")


@dataclass(frozen=True)
class FlagMaterial(Material):
    """The Turek–Hron flag's defaults (CSM1/FSI1: ρ 1000, μs 0.5 MPa → E 1.4 MPa, ν 0.4)."""

    density: float = positive(1000.0, "kg/m^3")
    young_modulus: float = positive(1.4e6, "Pa")
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

    stiffness: float = non_negative(0.0, "Pa/m")
    damping: float = non_negative(0.0, "Pa s/m")


@dataclass(frozen=True)
class PrestressLoad:
    """The load at which the drawn geometry is in equilibrium (docs/arterial-wall.md): the
    structure is solved from the stress-free reference that this ``pressure`` (Pa) on the
    interface takes to the drawn geometry (inverse elastostatics, fsi/physics/prestress.py),
    found by raising the pressure from 0 in ``load_steps`` steps; every run starts from it.
    E.g. the diastolic pressure of the artery the geometry was imaged at."""

    pressure: float = positive(10.7e3, "Pa")
    load_steps: int = at_least(20, 1)


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
    (no fluid solve); ``none`` solves it alone under ``body_force`` only (Turek–Hron CSM).
    ``prestress`` (:class:`PrestressLoad`, null: none): the geometry is drawn under that load,
    and the structure is solved from the stress-free reference it does not draw."""

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
    prestress: PrestressLoad | None = None
