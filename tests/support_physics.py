"""What only the tests need from the fluid and structure solvers: initial fields, the fluid's
traction as a field, the structure's first Piola traction load, its interface velocity and its
energies. Built on the solvers' public attributes and methods."""

from __future__ import annotations

import weakref
from collections.abc import Sequence

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx
import dolfinx.fem
import dolfinx.fem.petsc
import dolfinx.mesh
import numpy as np
import ufl

from fsi.geometry.tags import Boundary, Region
from fsi.physics.fluid import FluidSolver
from fsi.physics.fluid_boundaries import Velocity, as_tags
from fsi.physics.mesh import TaggedMesh
from fsi.physics.solid import SolidSolver

# --------------------------------------------------------------------------------------------
# The fluid


def _copy_to_mixed(
    U: dolfinx.fem.Function, source: dolfinx.fem.Function, source_to_U: np.ndarray
) -> None:
    owned = source_to_U >= 0
    U.x.array[source_to_U[owned]] = source.x.array[owned]
    U.x.scatter_forward()


def initialize(solver: FluidSolver, u=None, p=None) -> None:
    """Initial velocity (and pressure, a Newton initial guess) of ``solver``: Functions or
    callables x ↦ values as for ``Function.interpolate``; u^n = u^{n−1} = u. Default: rest."""
    V_to_W, Q_to_W = solver.mixed_dofs()
    if u is not None:
        solver.u.interpolate(u)
        solver.velocity_history.start()
        _copy_to_mixed(solver.U, solver.u, V_to_W)
    if p is not None:
        solver.p.interpolate(p)
        _copy_to_mixed(solver.U, solver.p, Q_to_W)


def traction(solver: FluidSolver, tags: Sequence[int] | None = None) -> dolfinx.fem.Function:
    """The traction (Pa) the fluid exerts on ``tags`` (default: the :class:`Velocity`
    boundaries) as a P2 field, nodal force / lumped boundary mass (f_i / ∫_Γ φ_i ds; exact for
    a constant traction), 0 off the boundary."""
    if tags is None:
        tags = [t for bc in solver.boundaries if isinstance(bc, Velocity) for t in bc.tags]
    tags = list(as_tags(tags))
    mesh = solver.mesh
    ds = ufl.Measure(
        "ds", domain=mesh, subdomain_data=solver.facet_tags, metadata={"quadrature_degree": 2}
    )
    v = ufl.TestFunction(solver.V)
    one = ufl.as_vector([1.0] * mesh.geometry.dim)
    mass = dolfinx.fem.petsc.assemble_vector(
        dolfinx.fem.form(
            sum((ufl.dot(one, v) * ds(t) for t in tags[1:]), ufl.dot(one, v) * ds(tags[0]))
        )
    )
    mass.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    field = dolfinx.fem.Function(solver.V, name="traction")
    gdim = mesh.geometry.dim
    nodal = solver.interface_force(tags)
    values = field.x.array.reshape(-1, gdim)
    values[nodal.dofs] = nodal.force / mass.array.reshape(-1, gdim)[nodal.dofs]
    field.x.scatter_forward()
    mass.destroy()
    return field


# --------------------------------------------------------------------------------------------
# The structure


def set_interface_traction(solver: SolidSolver, value: np.ndarray | dolfinx.fem.Function) -> None:
    """The first Piola traction t₀ (Pa) at t_{n+1} on the interface: a Function on the
    displacement space, or an interface vector (n, 2) of its values at the owned interface
    dofs."""
    if isinstance(value, dolfinx.fem.Function):
        solver.traction.x.array[:] = value.x.array
    else:
        values = solver.traction.x.array.reshape(-1, solver.V.dofmap.index_map_bs)
        values[solver.interface_dofs] = np.asarray(value).reshape(-1, values.shape[1])
        solver.traction.x.scatter_forward()


def interface_velocity(solver: SolidSolver) -> np.ndarray:
    """η̇_{n+1} (m/s) of the last step at the owned interface dofs, (n, 2)."""
    return solver.v.x.array.reshape(-1, 2)[solver.interface_dofs].copy()


_energy_forms: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def energies(solver: SolidSolver) -> tuple[float, float]:
    """Kinetic and stored energy of the committed state n, ``½∫ρ|η̇|²`` and ``∫W(F)`` (J/m)."""
    if solver not in _energy_forms:
        F = ufl.Identity(2) + ufl.grad(solver.eta_n)
        dx = solver.residual.dx
        _energy_forms[solver] = [
            dolfinx.fem.form(0.5 * solver.rho * ufl.inner(solver.v_n, solver.v_n) * dx),
            dolfinx.fem.form(solver.law.strain_energy(F) * dx),
        ]
    kinetic, stored = (
        float(solver.comm.allreduce(dolfinx.fem.assemble_scalar(form), op=MPI.SUM))
        for form in _energy_forms[solver]
    )
    return kinetic, stored


# --------------------------------------------------------------------------------------------
# Initial conditions, boundary data and interface vectors


def set_initial_conditions(solver: SolidSolver, eta0=None, v0=None) -> None:
    """Initial displacement and velocity of the structure (callables of x (3, n) → (2, n)); the
    initial acceleration is then made consistent with the loads
    (``SolidSolver.initialize_acceleration``)."""
    for f, value in ((solver.eta_n, eta0), (solver.v_n, v0)):
        if value is not None:
            f.interpolate(value)
            f.x.scatter_forward()
    solver.eta.x.array[:] = solver.eta_n.x.array
    if solver.scheme.dynamic:
        solver.initialize_acceleration()


def first_piola(law, F):
    """``P = F Σ(F)`` of a hyperelastic law."""
    return F * law.second_piola(F)


def set_boundary_displacement(mm, values: np.ndarray) -> None:
    """Set the mesh motion's boundary data g on its moving boundary from an interface vector:
    values (n, gdim) at the owned moving dofs ``mm.interface_dofs``."""
    values = np.asarray(values, dtype=float).reshape(len(mm.interface_dofs), mm.gdim)
    mm.g.x.array.reshape(-1, mm.gdim)[mm.interface_dofs] = values
    mm.g.x.scatter_forward()


def boundary_vector(mm, f=None) -> np.ndarray:
    """The interface vector (values at ``mm.interface_dofs``) of ``f`` (default: the mesh
    displacement d)."""
    f = mm.d if f is None else f
    return f.x.array.reshape(-1, mm.gdim)[mm.interface_dofs].copy()


def src_vector(imap, f) -> np.ndarray:
    """The interface vector of a function on an interface map's source space."""
    return f.x.array.reshape(-1, imap.bs)[imap.src_dofs].copy()


# --------------------------------------------------------------------------------------------
# A tube's wall as a meridian section (the axisymmetric structure's tests)


def meridian_section(
    inner: float,
    outer: float,
    length: float,
    cells: tuple[int, int],
    ends: tuple[Boundary, Boundary] = (Boundary.CLAMPED, Boundary.CLAMPED),
    comm: MPI.Comm = MPI.COMM_WORLD,
) -> TaggedMesh:
    """The wall [0, length] × [inner, outer] (x = z, y = r) of ``cells`` (axial, radial)
    triangles, region ``wall``; ``interface`` r = inner, ``exterior`` r = outer, and the ends
    z = 0 and z = length tagged ``ends``."""
    msh = dolfinx.mesh.create_rectangle(
        comm,
        [np.array([0.0, inner]), np.array([length, outer])],
        list(cells),
        dolfinx.mesh.CellType.triangle,
    )
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    index_map = msh.topology.index_map(tdim)
    n_cells = index_map.size_local + index_map.num_ghosts
    cell_tags = dolfinx.mesh.meshtags(
        msh, tdim, np.arange(n_cells, dtype=np.int32), np.full(n_cells, int(Region.WALL), np.int32)
    )
    sides = [
        (Boundary.INTERFACE, lambda x: np.isclose(x[1], inner)),
        (Boundary.EXTERIOR, lambda x: np.isclose(x[1], outer)),
        (ends[0], lambda x: np.isclose(x[0], 0.0)),
        (ends[1], lambda x: np.isclose(x[0], length)),
    ]
    facets, values = [], []
    for tag, where in sides:
        found = dolfinx.mesh.locate_entities_boundary(msh, tdim - 1, where)
        facets.append(found)
        values.append(np.full(len(found), int(tag), dtype=np.int32))
    facets, values = np.concatenate(facets), np.concatenate(values)
    facets, first = np.unique(facets, return_index=True)
    facet_tags = dolfinx.mesh.meshtags(msh, tdim - 1, facets.astype(np.int32), values[first])
    return TaggedMesh(msh, cell_tags, facet_tags)


def womersley_pipe(
    r: np.ndarray, radius: float, gradient: float, period: float, rho: float, mu: float
) -> tuple[np.ndarray, complex]:
    """Womersley's periodic pipe flow under the pressure gradient G cos(ωt) (``gradient`` G =
    the pressure drop's amplitude over the pipe's length, Pa/m; ω = 2π/``period``):
    u_axial(r, t) = Re(û(r) e^{iωt}), Q(t) = Re(Q̂ e^{iωt}) with

        û = A (1 − I₀(β r)/I₀(β R)),   Q̂ = A π R² (1 − 2 I₁(β R)/(β R I₀(β R))),

    A = G/(i ω ρ), β² = i ω ρ/μ (I₀, I₁ the modified Bessel functions; the solution of
    i ω ρ û = G + μ (û'' + û'/r) with û(R) = 0 and û'(0) = 0)."""
    import scipy.special

    omega = 2 * np.pi / period
    beta = np.sqrt(1j * omega * rho / mu)
    a = gradient / (1j * omega * rho)
    i0 = scipy.special.iv(0, beta * radius)
    u = a * (1 - scipy.special.iv(0, beta * r) / i0)
    q = a * np.pi * radius**2 * (1 - 2 * scipy.special.iv(1, beta * radius) / (beta * radius * i0))
    return u, q
