"""The fluid and the structure as the coupler's interface solvers
(:class:`fsi.coupled.coupling.InterfaceSolver`), through their solvers' public methods
(docs/model.md, Coupling).

:class:`FluidInterface` maps the interface displacement (m) to the fluid's nodal forces on the
structure (N/m) through the mesh motion, :class:`SolidInterface` those forces at t_{n+1} to its
interface displacement; both on flat interface vectors (the owned interface dofs of the solid's
displacement space). Forces are per metre of depth in the plane and in N (a whole ring) when
axisymmetric, as the residuals' integrals (fsi.physics.coordinates).
"""

from __future__ import annotations

import math

import dolfinx.fem
import numpy as np

from fsi.coupled.coupling import InterfaceUnknown
from fsi.coupled.interface import InterfaceMap
from fsi.coupled.robin import RobinCoefficient
from fsi.geometry.tags import Boundary
from fsi.numerics.newton import Forcing, SolveFailed, SolveResult
from fsi.physics.fluid import FluidSolver
from fsi.physics.mesh_motion import MeshMotion
from fsi.physics.solid import SolidSolver


class _Adapter:
    """What both sides share: ``begin_step``, ``save_state``, ``restore_state``, ``solve``,
    ``advance`` (:meth:`_solve` the subclass's step, :meth:`_output` its interface output), and the
    counters ``solves`` and ``newton_iterations`` of the current step and ``last``, the last
    solve's :class:`fsi.numerics.newton.SolveResult`.
    """

    def __init__(self, solver, warm_start: bool):
        self.solver, self.warm_start = solver, warm_start
        self.t, self.dt = math.nan, math.nan
        self.last: SolveResult | None = None
        self.newton_iterations = 0  # over the coupling iterations of the current step
        self.solves = 0  # coupling iterations of the current step so far
        self._checkpoint = None

    def begin_step(self, t: float, dt: float) -> None:
        """The step to solve next: to time ``t`` (s) with step ``dt`` (s)."""
        self.t, self.dt = t, dt
        self.newton_iterations = self.solves = 0

    def save_state(self) -> None:
        """Checkpoint the solver at the start of the step."""
        self._checkpoint = self.solver.save_state()

    def restore_state(self) -> None:
        """Back to the checkpoint; with ``warm_start`` the last iterate stays Newton's guess."""
        if self._checkpoint is None:
            raise RuntimeError("restore_state before save_state")
        self.solver.restore_state(self._checkpoint, warm_start=self.warm_start)

    def solve(self, interface_input: np.ndarray) -> np.ndarray:
        """One coupling iteration's solve: the interface input (flat) → the output (flat).
        Raises :class:`fsi.numerics.newton.SolveFailed` if the solver's step fails."""
        if not math.isfinite(self.dt):
            raise RuntimeError("call begin_step(t, dt) before solve")
        self.solves += 1
        self.last = None
        result = self._solve(np.asarray(interface_input))
        self.last = result
        self.newton_iterations += result.iterations
        self._raise_if_failed(result)
        return self._output().ravel()

    def advance(self) -> None:
        """Accept the last solve as the step's solution."""
        self.solver.advance()

    def _solve(self, interface_input: np.ndarray) -> SolveResult:
        raise NotImplementedError

    def _output(self) -> np.ndarray:
        raise NotImplementedError

    def _raise_if_failed(self, result: SolveResult) -> None:
        result.raise_if_failed()


class FluidInterface(_Adapter):
    """The fluid with its mesh motion: interface displacement (m) → the fluid's nodal forces on
    the structure (N/m), both solid interface vectors (:meth:`move_mesh`, step, :meth:`forces`).
    Every solve moves the mesh to its input (``coupling.geometry: implicit``; ``explicit``:
    :class:`ExplicitGeometryInterface`).

    Args:
        fluid_solver: the fluid, on the moving mesh.
        motion: the extension of the interface displacement into the fluid mesh.
        to_fluid, to_solid: the interface maps solid → fluid and fluid → solid.
        interface: the fluid's boundaries that meet the structure.
        warm_start: start each solve from the last iterate.
        forcing: the Newton forcing of a step's later solves, never looser than where its first
            stopped (:class:`fsi.numerics.newton.Forcing`; 0: every solve to the fluid's tolerance).
        alpha: the Robin–Neumann coupling's α(Δt) (:class:`fsi.coupled.robin.RobinCoefficient`)
            for a fluid with a Robin interface; None: Dirichlet–Neumann. The input of a solve
            is then z = [x, f] per node (:class:`fsi.coupled.coupling.InterfaceUnknown`): the
            mesh follows x, and the fluid's Robin data are α and the nodal forces f.

    Raises (collectively) :class:`fsi.physics.mesh_motion.MeshQualityError` when the extension
    would collapse a cell, and :class:`fsi.numerics.newton.SolveFailed` when the fluid step fails.
    """

    def __init__(
        self,
        fluid_solver: FluidSolver,
        motion: MeshMotion,
        to_fluid: InterfaceMap,
        to_solid: InterfaceMap,
        interface: tuple[Boundary, ...] = (Boundary.INTERFACE,),
        warm_start: bool = True,
        forcing: float = 0.0,
        alpha: RobinCoefficient | None = None,
    ):
        super().__init__(fluid_solver, warm_start)
        self.motion, self.to_fluid, self.to_solid = motion, to_fluid, to_solid
        self.interface = tuple(int(b) for b in interface)
        self.forcing = forcing
        self.alpha = alpha
        self.unknown = InterfaceUnknown(to_solid.bs, forces=alpha is not None)
        self._nodes = to_solid.comm.allreduce(len(to_solid.dst_dofs))  # interface nodes, global
        self.first_residual = math.nan  # |F| where the step's first solve stopped
        self.eta = dolfinx.fem.Function(fluid_solver.V, name="interface_displacement")
        self.mesh_quality = 1.0  # min J/J_ref of the last mesh motion

    def _set_interface(self, x: np.ndarray) -> None:
        """η_Γ ← x (on the fluid's P2 interface nodes), and its vertex values as the mesh
        motion's boundary data g."""
        self.to_fluid.set_dst(
            self.eta, self.to_fluid.transfer(np.asarray(x).reshape(-1, self.to_fluid.bs))
        )
        self.motion.set_boundary_function(self.eta)

    def _extend(self) -> None:
        """d = the extension of the motion's boundary data g (quality-checked before the mesh
        moves); the mesh to X + d."""
        self.motion.solve()
        self.mesh_quality = self.motion.check_quality()
        self.solver.set_mesh_displacement(self.motion.d)

    def start_from(self, x: np.ndarray) -> None:
        """An initial state other than rest: the mesh at X + d, the extension of the interface
        displacement x, taken as at rest there (d^n = d^{n−1} = d)."""
        self._set_interface(x)
        self._extend()
        self.solver.ale.history.start()

    def move_mesh(self, x: np.ndarray) -> None:
        """η_Γ ← x; the mesh to X + d, d the extension of η_Γ's vertex values; boundary
        velocity u_Γ = w = Σ_k a_k d^{n+1−k}, which the step then uses: the moving wall is
        material, ``(u − w)·n = 0``."""
        fluid = self.solver
        self._set_interface(x)
        self._extend()
        fluid.set_boundary_velocity(fluid.mesh_velocity(self.dt))

    def forces(self) -> np.ndarray:
        """The fluid's nodal forces on the structure as a solid interface vector (n, gdim), N/m."""
        values = self.solver.nodal_forces(self.interface)
        return self.to_solid.transfer(values[self.to_solid.src_dofs])

    def weights(self) -> np.ndarray | None:
        """The weights that measure this step's iterates z in metres
        (:meth:`fsi.coupled.coupling.InterfaceUnknown.weights`): with Robin–Neumann, 1 on x and
        c = Δt / (α Ā) on f, Ā the interface's area per node: a change δf of the Robin data
        leaves the slip u − u_Γ = δf / (α Ā) at a node, c δf over one step. None without."""
        if self.alpha is None:
            return None
        area_per_node = self.solver.robin.area / self._nodes
        size = len(self.to_solid.dst_dofs) * self.unknown.block
        return self.unknown.weights(size, self.dt / (self.alpha.at(self.dt) * area_per_node))

    def _set_robin_data(self, nodal_forces: np.ndarray) -> None:
        """The fluid's Robin data: α(Δt) and the nodal forces (a solid interface vector) on its
        velocity nodes."""
        V = self.solver.V
        forces = np.zeros((V.dofmap.index_map.size_local, V.dofmap.index_map_bs))
        forces[self.to_fluid.dst_dofs] = self.to_fluid.transfer(
            nodal_forces.reshape(-1, self.to_fluid.bs)
        )
        self.solver.robin.set(self.alpha.at(self.dt), forces, self.solver.mixed_dofs()[0])

    def _solve(self, interface_input: np.ndarray) -> SolveResult:
        if self.alpha is not None:  # z = [x, f]
            self._set_robin_data(self.unknown.nodal_forces(interface_input))
            interface_input = self.unknown.displacement(interface_input)
        self._place_mesh(interface_input)
        forcing = None
        if self.forcing and self.solves > 1:
            forcing = Forcing(self.forcing, ceiling=self.first_residual)
        result = self.solver.step(self.t, self.dt, forcing=forcing)
        if self.solves == 1:
            self.first_residual = result.residual
        return result

    def _output(self) -> np.ndarray:
        return self.forces()

    def _place_mesh(self, interface_input: np.ndarray) -> None:
        """The mesh of a solve: moved to its input (:meth:`move_mesh`)."""
        self.move_mesh(interface_input)


class ExplicitGeometryInterface(FluidInterface):
    """:class:`FluidInterface` with ``coupling.geometry: explicit`` (the geometry-convective
    explicit scheme of Badia, Quaini & Quarteroni 2008 and Crosetto et al. 2011): a step's first
    solve moves the mesh to its input, the predictor's extrapolation, and its later ones keep
    that mesh (:meth:`hold_mesh`), so the fluid's matrix is the same in all of them, and with a
    linear (``extrapolated``) fluid and ``jacobian_reuse: step`` it is factorised once per step.
    The wall's velocity still follows each iterate x_k, u_Γ = a0 x_k + a1 d^n + a2 d^{n−1} (the
    BDF derivative of the interface displacement, as with ``implicit``): the pressure stays
    implicitly coupled to the wall. It differs from the mesh's own velocity w on Γ by
    a0 (x_k − x_0), so (u − w)·n ≠ 0 there by the predictor's error. Once the step is accepted
    the mesh moves to the extension of the last input (:meth:`advance`), so the displacement
    history d^n, d^{n−1} is the same as with ``implicit``."""

    def __init__(self, fluid_solver: FluidSolver, motion: MeshMotion, *args, **kwargs):
        super().__init__(fluid_solver, motion, *args, **kwargs)
        # The interface data g of the step's first solve (P1, the motion's layout; its
        # extension stays in motion.d until the step is accepted) and the wall velocity set
        # from it.
        self._held_g = np.zeros_like(motion.g.x.array)
        self._wall_velocity = dolfinx.fem.Function(fluid_solver.ale.space)
        if len(self._held_g) != len(self._wall_velocity.x.array):
            raise RuntimeError("the mesh motion's and the fluid mesh's P1 spaces differ")

    def move_mesh(self, x: np.ndarray) -> None:
        """:meth:`FluidInterface.move_mesh`, keeping the interface data g it moved to."""
        super().move_mesh(x)
        self._held_g[:] = self.motion.g.x.array

    def hold_mesh(self, x: np.ndarray) -> None:
        """Explicit geometry's later coupling iterations: the mesh back to X + d of the step's
        first solve (restoring the step's start moved it; the motion still holds that d) with its
        velocity w, and the wall's velocity u_Γ = w + a0 (g(x) − g(x_0)) on the interface's
        vertices, g the vertex values of η_Γ: the BDF derivative of the interface displacement x
        (class docstring)."""
        fluid = self.solver
        fluid.set_mesh_displacement(self.motion.d)
        w = fluid.mesh_velocity(self.dt)
        self._set_interface(x)
        a0 = fluid.time_weights(self.dt)[0]
        self._wall_velocity.x.array[:] = w.x.array + a0 * (self.motion.g.x.array - self._held_g)
        fluid.set_boundary_velocity(self._wall_velocity)

    def _place_mesh(self, interface_input: np.ndarray) -> None:
        """The step's first solve moves the mesh, its later ones hold it."""
        if self.solves > 1:
            self.hold_mesh(interface_input)
        else:
            self.move_mesh(interface_input)

    def advance(self) -> None:
        """Accept the last solve; after a held mesh it first moves to the extension of the last
        input (whose vertex values :meth:`hold_mesh` left in g), where ``implicit`` left it (the
        next step's d^n)."""
        if self.solves > 1:
            self._extend()
        super().advance()


class SolidInterface(_Adapter):
    """The structure: the fluid's nodal forces at t_{n+1} (N/m) → its interface displacement
    (m), both flat interface vectors. A failed step raises :class:`SolveFailed`."""

    def __init__(self, solver: SolidSolver, warm_start: bool = True):
        super().__init__(solver, warm_start)

    def _solve(self, interface_input: np.ndarray) -> SolveResult:
        dimension = self.solver.interface_points.shape[1]
        self.solver.set_interface_forces(interface_input.reshape(-1, dimension))
        return self.solver.step(self.t, self.dt)

    def _output(self) -> np.ndarray:
        return self.solver.interface_displacement()

    def _raise_if_failed(self, result: SolveResult) -> None:
        if not result.converged:
            raise SolveFailed(
                f"structure step to t = {self.t:g} s failed: {result.reason}"
                f" (residual {result.residual:.3g})"
            )
