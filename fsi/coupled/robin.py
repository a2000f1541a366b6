"""The Robin coefficient α of the Robin–Neumann coupling (``coupling.scheme: robin-neumann``).

The fluid's interface condition is α (u − u_Γ) − σ n = t_k (fsi/physics/fluid_boundaries.py,
:class:`~fsi.physics.fluid_boundaries.Robin`). The iterations converge fastest when α is the
structure's own answer to the wall's velocity, traction per velocity (Badia, Nobile & Vergara
2008, J. Comput. Phys. 227:7027–7051, for a wall of the generalized string model). For a wall of
thickness H, density ρ_s, Young's modulus E and Poisson's ratio ν on a lumen of radius R, a
step of Δt that moves the wall by Δt v against its inertia ρ_s H v/Δt and its hoop stiffness
E H/((1 − ν²) R²) · Δt v gives

    α = ρ_s H / Δt + E H Δt / ((1 − ν²) R²)

(the plane models have no hoop stiffness: α = ρ_s H / Δt). ``coupling.robin_coefficient``
replaces it with a number.
"""

from __future__ import annotations

from dataclasses import dataclass

from fsi import config


@dataclass(frozen=True)
class RobinCoefficient:
    """α(Δt) = ``inertia`` / Δt + ``stiffness`` · Δt (Pa·s/m), or ``fixed`` when given."""

    inertia: float = 0.0  # ρ_s H, kg/m²
    stiffness: float = 0.0  # E H / ((1 − ν²) R²), Pa/m
    fixed: float | None = None

    def at(self, dt: float) -> float:
        """α for a step of ``dt`` (s)."""
        if self.fixed is not None:
            return self.fixed
        return self.inertia / dt + self.stiffness * dt


def from_case(case: config.Case) -> RobinCoefficient:
    """The case's α: ``coupling.robin_coefficient``, or the module docstring's from the wall: the
    vessel wall's material and ``wall_thickness`` (stenosis, tube) or the Turek–Hron flag's and
    its thickness, with the hoop term on the lumen's radius (``height`` of a stenosis,
    ``radius`` of a tube) when the vessel is axisymmetric or 3D."""
    if case.coupling.robin_coefficient is not None:
        return RobinCoefficient(fixed=case.coupling.robin_coefficient)
    g = case.geometry
    if isinstance(g, config.TurekHronGeometry):
        material, thickness, radius = case.structure.flag, g.flag_thickness, None
    elif isinstance(g, (config.StenosisGeometry, config.TubeGeometry)):
        material, thickness = case.structure.wall, g.wall_thickness
        circular = config.is_axisymmetric(g) or config.dimension(g) == 3
        lumen = g.height if isinstance(g, config.StenosisGeometry) else g.radius
        radius = lumen if circular else None
    else:
        raise ValueError(f"coupling.robin_coefficient: no wall to take it from in {g.kind!r}")
    E, nu = material.young_modulus, material.poisson_ratio
    hoop = 0.0 if radius is None else E * thickness / ((1 - nu**2) * radius**2)
    return RobinCoefficient(inertia=material.density * thickness, stiffness=hoop)
