"""The ``coupling`` section (:class:`Coupling`: the fluid–structure iterations of a step) and
the ``mesh_motion`` section (:class:`MeshMotionSettings`: the ALE extension done in each of them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from fsi.config.reader import at_least, checked, non_negative, open_interval, positive
from fsi.config.solver_settings import direct_solver_options


@dataclass(frozen=True)
class Coupling:
    """Dirichlet–Neumann iterations per step (docs/model.md §5; fsi/coupled/coupling.py).

    ``initial_relaxation``: ω of constant relaxation, Aitken's first ω and IQN-ILS's relaxed
    first iteration; ``max_relaxation``: Aitken's cap |ω| <= ω_max; ``iqn_reuse``: time steps
    whose secant columns IQN-ILS reuses; ``iqn_filter``: its QR filter threshold (relative);
    ``predictor``: extrapolation of the interface displacement from previous steps;
    ``fluid_forcing``: from a step's second coupling iteration on, a fluid solve stops once it
    has reduced its initial residual by this factor (never looser than where the step's first
    solve stopped; fsi/coupled/partitioned.py); 0 solves each to the fluid's Newton tolerance.
    ``geometry``: ``implicit`` moves the fluid mesh in every coupling iteration; ``explicit``
    only in a step's first, to the predicted interface displacement, and keeps that mesh (and
    its velocity) through the step's later iterations, where only the wall's velocity follows
    the iterate (fsi/coupled/adapters.py, :class:`ExplicitGeometryInterface`).
    ``scheme``: ``dirichlet-neumann`` gives the fluid the wall's velocity on the interface;
    ``robin-neumann`` gives it the Robin condition α (u − u_Γ) − σ n = the traction of the last
    iteration (Badia, Nobile & Vergara 2008; docs/model.md, Coupling), which converges to the
    same solution with fewer iterations where the fluid's added mass is large.
    ``robin_coefficient``: α (Pa·s/m); null: from the wall, α = ρ_s H/Δt + E H Δt/((1 − ν²) R²)
    (fsi/coupled/robin.py).
    """

    acceleration: Literal["constant", "aitken", "iqn-ils"] = "aitken"
    tolerance: float = positive(1.0e-6)
    max_iterations: int = at_least(50, 1)
    initial_relaxation: float = checked(0.5, lambda v: 0 < v <= 1, "a number in (0, 1]")
    max_relaxation: float = positive(1.0)
    iqn_reuse: int = at_least(4, 0)
    iqn_filter: float = positive(1.0e-2)  # 1e-8 kept stale columns: IQN diverged on the stenosis
    predictor: Literal["constant", "linear", "quadratic", "cubic"] = "linear"
    fluid_forcing: float = checked(0.0, lambda v: 0 <= v < 1, "a number in [0, 1)")
    geometry: Literal["implicit", "explicit"] = "implicit"
    scheme: Literal["dirichlet-neumann", "robin-neumann"] = "dirichlet-neumann"
    robin_coefficient: float | None = checked(
        None, lambda v: v is None or v > 0, "a positive number, or null for the wall's", "Pa s/m"
    )


@dataclass(frozen=True)
class MeshMotionSettings:
    """ALE extension of the interface displacement into the fluid (docs/model.md §5;
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
    petsc_options: dict[str, str | int | float] = field(default_factory=direct_solver_options)
