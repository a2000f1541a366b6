"""The partitioned fluid–structure problem of MODEL.md §5: the fluid side as the coupler's
interface solver, and the assembly of a coupled case from one mesh.

Per coupling iteration the fluid side maps the interface displacement x (the solid's owned
interface dofs, flat) to the force the blood exerts on the structure:

1. η_Γ: x is transferred to the fluid's P2 interface nodes
   (:class:`fsi.coupled.interface.InterfaceMap`, pairing by position on the reference
   configuration);
2. mesh motion (fsi/physics/mesh_motion.py): the P1 vertex values of η_Γ are the Dirichlet data
   ``g`` of the extension ``d`` (:class:`~fsi.physics.mesh_motion.MeshMotion`, the extension
   operator: ``solve``, and the quality guard ``check_quality``, which judges X + d and raises
   before the mesh moves; it keeps no time levels); the fluid's
   :class:`~fsi.physics.mesh_motion.AleMesh` (``FluidSolver.ale``) then moves the mesh to
   ``x = X + d``. The AleMesh is the one object that writes the mesh coordinates and the one
   owner of the displacement history d^n, d^{n−1} and of ``w``;
3. kinematic condition: ``u = w`` on Γw1, with ``w = Σ_k a_k d^{n+1−k}`` the fluid scheme's BDF
   derivative of the mesh displacement (the same weights as ∂u/∂t), interpolated into P2. So the
   moving wall is exactly material for the discrete fluid (no flux through Γw1 relative to the
   mesh: ``(u − w)·n = 0``), and the velocity the fluid sees is the velocity of *its* boundary,
   the piecewise-linear interpolant of η (the P1 geometry), which is what the geometric
   conservation of the ALE form needs. At convergence ``d|Γ = η`` so ``u = ∂η/∂t`` holds to the
   order of the BDF formula; the solid's generalized-α velocity differs from it by O(Δt²)
   (it belongs to another time scheme and to the solid's output, not to the input x);
4. the fluid step (Newton) on the moved mesh, from the last iterate (``warm_start``). The
   step's first solve stops on the fluid's own Newton test; the later ones, which start near
   their answer, stop once they have reduced their initial residual by ``forcing`` (the
   coupling's ``fluid_forcing``), but never looser than where the step's first solve stopped
   (:class:`fsi.numerics.newton.Forcing`): the dolfinx test, relative to a warm start's small
   first increment, would solve each of them some 1e4 times tighter than the first;
5. the output: the residual-based nodal forces ``f_i = −R_i = −∫_Γ σ n_f φ_i ds`` of the fluid
   (:meth:`fsi.physics.fluid.FluidSolver.interface_force`; n_f the fluid's outward normal, so this
   is ``∫ σ n_s φ_i ds`` with n_s = −n_f: the force of the fluid ON the structure, N per unit
   depth), transferred to the solid's interface dofs. :class:`fsi.physics.solid.CoupledSolid` adds
   such nodal forces to its external load as they are (``load="forces"``). Nodal forces are
   configuration-independent vectors, so the total-Lagrangian solid takes them unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mpi4py import MPI

import dolfinx.fem
import numpy as np

from fsi import config
from fsi.coupled import coupling
from fsi.coupled.interface import InterfaceMap
from fsi.numerics.newton import Forcing, SolveResult
from fsi.physics import fluid, mesh, solid
from fsi.physics.mesh_motion import MeshMotion
from geometry.tags import Boundary, Region


class FluidInterface:
    """The fluid (with its mesh motion) as a :class:`fsi.coupled.coupling.InterfaceSolver`.

    ``solve(x)``: interface displacement (solid interface vector, flat, m) → nodal forces of the
    fluid on the structure (solid interface vector, flat, N/m); see the module docstring.
    ``restore_state`` goes back to the start of the step (solution history and mesh position)
    but keeps the last (u, p) as Newton's initial guess (``warm_start``). The mesh motion has
    no state to save: its ``g`` and ``d`` are recomputed from x in every iteration; the mesh
    position, the displacement history and ``w`` belong to the fluid's AleMesh, which the
    fluid's own save/restore/advance cover.

    Raises (collectively) :class:`fsi.physics.mesh_motion.MeshQualityError` when the extension would
    collapse a cell, and :class:`fsi.numerics.newton.SolveFailed` when the fluid step fails.
    """

    def __init__(
        self,
        fluid_solver: fluid.FluidSolver,
        motion: MeshMotion,
        to_fluid: InterfaceMap,
        to_solid: InterfaceMap,
        interface: tuple[Boundary, ...] = (Boundary.INTERFACE,),
        warm_start: bool = True,
        forcing: float = 0.0,
    ):
        self.fluid, self.motion = fluid_solver, motion
        self.to_fluid, self.to_solid = to_fluid, to_solid
        self.interface, self.warm_start = tuple(int(b) for b in interface), warm_start
        self.forcing = forcing  # 0: every solve to the fluid's Newton tolerance
        self.first_residual = math.nan  # |F| where the step's first solve stopped
        self.eta = dolfinx.fem.Function(fluid_solver.V, name="interface_displacement")
        self.t, self.dt = math.nan, math.nan
        self.last: SolveResult | None = None
        self.newton_iterations = 0  # over the coupling iterations of the current step
        self.solves = 0  # coupling iterations of the current step so far
        self.mesh_quality = 1.0  # min J/J_ref of the last mesh motion

    def begin_step(self, t: float, dt: float) -> None:
        self.t, self.dt = t, dt
        self.newton_iterations = self.solves = 0

    def save_state(self) -> None:
        self.fluid.save_state()

    def restore_state(self) -> None:
        guess = self.fluid.U.x.array.copy()
        self.fluid.restore_state()
        if self.warm_start:  # U is only Newton's initial guess: u^n, u^{n−1} are separate
            self.fluid.U.x.array[:] = guess

    def move_mesh(self, x: np.ndarray) -> None:
        """η_Γ ← x; d = extension of η_Γ's vertex values (quality-checked); mesh to X + d;
        boundary velocity u_Γ = w = Σ_k a_k d^{n+1−k}."""
        f = self.fluid
        self.to_fluid.set_dst(self.eta, self.to_fluid.transfer(np.asarray(x).reshape(-1, 2)))
        self.motion.set_boundary_function(self.eta)
        self.motion.solve()
        self.mesh_quality = self.motion.check_quality()
        f.set_mesh_displacement(self.motion.d)  # the fluid's AleMesh moves the mesh
        f.ale.set_velocity(f.time_weights(self.dt))  # step() recomputes the same w
        f.boundary_velocity.interpolate(f.ale.w)
        f.boundary_velocity.x.scatter_forward()

    def solve(self, interface_input: np.ndarray) -> np.ndarray:
        if not math.isfinite(self.dt):
            raise RuntimeError("call begin_step(t, dt) before solve")
        self.solves += 1
        self.move_mesh(interface_input)
        forcing = None
        if self.forcing and self.solves > 1:
            forcing = Forcing(self.forcing, ceiling=self.first_residual)
        result = self.fluid.step(self.t, self.dt, forcing=forcing)
        if self.solves == 1:
            self.first_residual = result.residual
        self.last = result
        self.newton_iterations += result.iterations
        result.raise_if_failed()
        return self.forces().ravel()

    def forces(self) -> np.ndarray:
        """The fluid's nodal forces on the structure as a solid interface vector (n, 2)."""
        nodal = self.fluid.interface_force(self.interface)
        gdim = self.fluid.mesh.geometry.dim
        values = np.zeros((self.fluid.V.dofmap.index_map.size_local, gdim))
        values[nodal.dofs] = nodal.force
        return self.to_solid.transfer(values[self.to_solid.src_dofs])

    def advance(self) -> None:
        self.fluid.advance()


class SolidInterface(solid.CoupledSolid):
    """:class:`fsi.physics.solid.CoupledSolid` that also counts the Newton iterations of a step's
    coupling iterations (``newton_iterations``)."""

    def __init__(self, solver: solid.SolidSolver):
        super().__init__(solver, load="forces")
        self.newton_iterations = 0

    def begin_step(self, t: float, dt: float) -> None:
        super().begin_step(t, dt)
        self.newton_iterations = 0

    def solve(self, interface_input: np.ndarray) -> np.ndarray:
        self.last = None
        try:
            return super().solve(interface_input)
        finally:
            if self.last is not None:
                self.newton_iterations += self.last.iterations


@dataclass
class CoupledProblem:
    """Everything a coupled run needs, built from one mesh of the whole system."""

    whole: mesh.TaggedMesh
    fluid_mesh: mesh.TaggedMesh
    fluid: fluid.FluidSolver
    motion: MeshMotion
    fluid_side: FluidInterface
    solid: solid.SolidSolver
    solid_side: SolidInterface
    acceleration: coupling.Acceleration
    predictor: coupling.Predictor
    settings: config.Coupling

    def begin_step(self, t: float, dt: float) -> None:
        self.fluid_side.begin_step(t, dt)
        self.solid_side.begin_step(t, dt)

    def step(self, index: int, t: float, dt: float) -> coupling.StepResult:
        """The Dirichlet–Neumann iterations of the step ending at ``t`` (collective)."""
        self.begin_step(t, dt)
        return coupling.couple_step(
            self.fluid_side,
            self.solid_side,
            self.acceleration,
            self.predictor,
            self.fluid.comm,
            tolerance=self.settings.tolerance,
            max_iterations=self.settings.max_iterations,
            step=index,
            t=t,
        )

    @property
    def relaxation(self) -> float | None:
        """The relaxation factor ω of the last iteration (Aitken, constant), else None."""
        return self.acceleration.relaxation


def build_coupled(case: config.Case, comm: MPI.Comm = MPI.COMM_WORLD) -> CoupledProblem:
    """Build the coupled problem of ``case`` (structure.mode fixed_wall or moving_wall): one mesh
    of the fluid and the structure (the stenosis' wall + cap + lipid, or the Turek–Hron flag),
    its fluid and structure submeshes (with the parent's tags), the fluid solver with the
    study's boundaries (no-slip on the rigid walls and the Turek–Hron cylinder), the mesh
    motion, the solid with the mode's Dirichlet conditions, the interface maps, the acceleration
    and the predictor (initialised with the structure at rest). Collective."""
    if case.structure.mode == "rigid":
        raise ValueError("structure.mode 'rigid' has no structure to couple")
    whole = mesh.build(case, comm)
    fluid_mesh = mesh.restrict(whole, Region.FLUID)
    boundaries = fluid.boundary_conditions(
        case.fluid, mesh.geometry_module(case).BOUNDARIES, moving_interface=True
    )
    fluid_solver = fluid.FluidSolver(
        fluid_mesh.mesh, fluid_mesh.facet_tags, case.fluid, boundaries, scheme=case.time.scheme
    )
    # Built before the mesh ever moves: both keep the reference coordinates X.
    motion = MeshMotion(fluid_mesh, case.mesh_motion, moving=(Boundary.INTERFACE,))
    solid_solver = solid.build(case, whole, comm)
    fluid_facets = fluid_mesh.facets(Boundary.INTERFACE)
    to_fluid = InterfaceMap(
        solid_solver.V, solid_solver.interface_facets, fluid_solver.V, fluid_facets
    )
    to_solid = InterfaceMap(
        fluid_solver.V, fluid_facets, solid_solver.V, solid_solver.interface_facets
    )
    if not (
        np.array_equal(to_fluid.src_dofs, solid_solver.interface_dofs)
        and np.array_equal(to_solid.dst_dofs, solid_solver.interface_dofs)
    ):
        raise RuntimeError("the solid's interface vector and the interface maps disagree")
    fluid_side = FluidInterface(
        fluid_solver, motion, to_fluid, to_solid, forcing=case.coupling.fluid_forcing
    )
    solid_side = SolidInterface(solid_solver)
    predictor = coupling.predictor_from_config(case.coupling)
    predictor.record(solid_solver.interface_displacement().ravel(), 0.0)
    return CoupledProblem(
        whole,
        fluid_mesh,
        fluid_solver,
        motion,
        fluid_side,
        solid_solver,
        solid_side,
        coupling.from_config(case.coupling, comm),
        predictor,
        case.coupling,
    )
