"""The partitioned fluid–structure problem (docs/model.md, Coupling), assembled from one mesh of
the whole system: the fluid and structure solvers, the mesh motion, the interface maps, the two
sides of the coupler (fsi/coupled/adapters.py), the acceleration and the predictor, and the
Dirichlet–Neumann (or Robin–Neumann, fsi/coupled/robin.py) step that joins them
(fsi/coupled/coupling.py).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from mpi4py import MPI

import numpy as np

from fsi import config
from fsi.coupled import coupling, robin
from fsi.coupled.adapters import ExplicitGeometryInterface, FluidInterface, SolidInterface
from fsi.coupled.interface import InterfaceMap
from fsi.geometry.tags import Boundary, Region
from fsi.physics import fluid, fluid_boundaries, fluid_case, mesh, solid, solid_boundaries
from fsi.physics.mesh_motion import MeshMotion


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
        """Both sides' next step: to time ``t`` (s) with step ``dt`` (s)."""
        self.fluid_side.begin_step(t, dt)
        self.solid_side.begin_step(t, dt)

    @property
    def unknown(self) -> coupling.InterfaceUnknown:
        """What the iterations solve for: x, or [x, f] with Robin–Neumann."""
        return self.fluid_side.unknown

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
            unknown=self.unknown,
            weights=self.fluid_side.weights(),
        )

    @property
    def relaxation(self) -> float | None:
        """The relaxation factor ω of the last iteration (Aitken, constant), else None."""
        return self.acceleration.relaxation


def build_coupled(
    case: config.Case,
    comm: MPI.Comm = MPI.COMM_WORLD,
    *,
    fluid_conditions: Sequence[fluid_boundaries.BoundaryCondition] | None = None,
    solid_conditions: solid_boundaries.SolidBoundaryConditions | None = None,
) -> CoupledProblem:
    """Build the coupled problem of ``case`` (structure.mode fixed_wall or moving_wall): one mesh
    of the fluid and the structure (the stenosis' wall + cap + lipid, or the Turek–Hron flag),
    its fluid and structure submeshes (with the parent's tags), the fluid solver with the
    study's boundaries (no-slip on the rigid walls and the Turek–Hron cylinder), the mesh
    motion, the solid with the mode's Dirichlet conditions, the interface maps, the acceleration
    and the predictor (initialised with the structure at rest). ``fluid_conditions`` and
    ``solid_conditions`` replace the case's boundary conditions (data no case file states,
    such as an exact solution imposed at a verification case's ends). Collective."""
    if case.structure.mode == "rigid":
        raise ValueError("structure.mode 'rigid' has no structure to couple")
    whole = mesh.build(case, comm)
    fluid_mesh = mesh.restrict(whole, Region.FLUID)
    fluid_solver = fluid_case.fluid_solver(
        case, fluid_mesh, moving_interface=True, conditions=fluid_conditions
    )
    # Built before the mesh ever moves: both keep the reference coordinates X.
    motion = MeshMotion(
        fluid_mesh,
        case.mesh_motion,
        moving=(Boundary.INTERFACE,),
        symmetry_planes=config.symmetry_planes(case.geometry),
    )
    solid_solver = solid.build(case, whole, comm, bcs=solid_conditions)
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
    fluid_side = _fluid_side(case, fluid_solver, motion, to_fluid, to_solid)
    solid_side = SolidInterface(solid_solver)
    predictor = coupling.predictor_from_config(case.coupling)
    z0 = fluid_side.unknown.stack(solid_solver.interface_displacement())
    predictor.record(z0, 0.0)
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


def _fluid_side(case: config.Case, fluid_solver, motion, to_fluid, to_solid) -> FluidInterface:
    """The fluid's side of the coupler: ``coupling.geometry`` chooses the adapter,
    ``coupling.scheme`` the interface condition (Robin–Neumann: with α, fsi/coupled/robin.py)."""
    explicit = case.coupling.geometry == "explicit"
    interface = ExplicitGeometryInterface if explicit else FluidInterface
    robin_neumann = case.coupling.scheme == "robin-neumann"
    return interface(
        fluid_solver,
        motion,
        to_fluid,
        to_solid,
        forcing=case.coupling.fluid_forcing,
        alpha=robin.from_case(case) if robin_neumann else None,
    )
