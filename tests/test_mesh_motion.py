"""ALE mesh motion of the fluid (fsi/physics/mesh_motion.py), serially and on 2 ranks.

The mesh is the default case's coarse stenosis fluid submesh: lumen 7 mm high, a 1 cm plaque on
the bottom reaching half the height, so the lumen is 3.5 mm wide at the plaque's apex.
"""

from mpi4py import MPI
from petsc4py import PETSc

import dolfinx.fem
import numpy as np
import pytest
import support_physics
from mesh_checks import global_max, mesh_motion_settings

from fsi import compat, config
from fsi.geometry.tags import Boundary, Region
from fsi.numerics.timestepping import bdf_weights
from fsi.physics import mesh
from fsi.physics.mesh_motion import AleMesh, MeshMotion, MeshQualityError

CASE = config.from_dict({})
G = CASE.geometry
X0, LS = G.length / 2 - G.stenosis_length / 2, G.stenosis_length  # the plaque's extent in x
FLUID_BOUNDARIES = (Boundary.INLET, Boundary.OUTLET, Boundary.INTERFACE, Boundary.RIGID_WALL)


def bump(amplitude: float):
    """d = A (1 − cos(2π s))/2 e_y with s = (x − x0)/l clipped to [0, 1]: smooth, zero (with
    zero slope) at the plaque's ends; A > 0 pushes the plaque towards the opposite wall."""

    def f(x):
        s = np.clip((x[0] - X0) / LS, 0.0, 1.0)
        return np.vstack([np.zeros_like(x[0]), amplitude * 0.5 * (1 - np.cos(2 * np.pi * s))])

    return f


def fluid_submesh(comm: MPI.Comm) -> mesh.TaggedMesh:
    return mesh.restrict(mesh.build(CASE, comm), Region.FLUID)


@pytest.fixture(scope="module")
def fluid():
    return fluid_submesh(MPI.COMM_WORLD)


@pytest.fixture(autouse=True)
def _reference_geometry(fluid):
    """Every test starts and ends on the reference mesh (AleMesh moves the shared mesh)."""
    x = fluid.mesh.geometry.x.copy()
    yield
    fluid.mesh.geometry.x[:] = x


def boundary_nodes(tagged: mesh.TaggedMesh, *boundaries: Boundary) -> np.ndarray:
    nodes = compat.entities_to_geometry(tagged.mesh, 1, tagged.facets(*boundaries))
    return np.unique(nodes.ravel())


# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", ["harmonic", "elastic"])
def test_affine_boundary_displacement_is_extended_exactly(fluid, method):
    """An affine d = a + B X on the whole boundary is the exact solution of both extension
    problems with constant k (∇d constant: −∇·∇d = 0 and ∇·σ(d) = 0), and P1 holds it exactly,
    so the discrete extension equals it at every interior dof up to solver round-off."""
    B = np.array([[0.02, -0.05], [0.03, 0.01]])
    a = np.array([1e-4, -2e-4])

    def affine(x):
        return a[:, None] + B @ x[:2]

    mm = MeshMotion(
        fluid,
        mesh_motion_settings(method=method, stiffening="none"),
        moving=FLUID_BOUNDARIES,
        fixed=(),
    )
    mm.set_boundary_function(affine)
    mm.solve()
    n_owned = mm.V.dofmap.index_map.size_local
    exact = affine(mm.dof_points[:n_owned].T).T
    error = global_max(fluid.comm, mm.d.x.array.reshape(-1, 2)[:n_owned] - exact)
    scale = global_max(fluid.comm, exact)
    # LU on a matrix of condition ~1e4 (h ≈ 0.2 mm in a 2 cm domain): ~1e-12 relative.
    assert error < 1e-10 * scale, (method, error / scale)
    # Interior dofs do move (the test is not passed by boundary values alone).
    interior = np.setdiff1d(np.arange(n_owned), mm._moving_dofs)
    assert fluid.comm.allreduce(len(interior)) > 100


def test_bump_moves_interface_nodes_exactly_and_keeps_the_other_boundaries(fluid):
    A = 5e-4  # 0.5 mm: a seventh of the 3.5 mm lumen at the apex
    mm = MeshMotion(fluid)  # the defaults: harmonic, Jacobian stiffening
    ale = AleMesh(fluid.mesh)  # the one object that moves the mesh
    assert mm.fixed == (Boundary.INLET, Boundary.OUTLET, Boundary.RIGID_WALL)
    values = bump(A)(mm.interface_points.T).T  # an interface vector, as the coupler sets it
    support_physics.set_boundary_displacement(mm, values)
    mm.solve()
    mm.check_quality()
    ale.move(mm.d)  # the coupler's order: set, solve, check quality, move

    x, X = fluid.mesh.geometry.x, mm.reference
    cap = boundary_nodes(fluid, Boundary.INTERFACE)
    # The boundary values are copied into d, not solved for: exactly the values set.
    assert np.array_equal(support_physics.boundary_vector(mm), values)
    # And the mesh is at X + d there, to the coordinates' last bits, not bit for bit: `values` are
    # the bump at the P1 dofs' coordinates, which the BLAS computes from the geometry's nodes
    # (OpenBLAS leaves them a last bit apart: 4e-19 m in 2 cm).
    last_bits = 4 * np.finfo(float).eps * global_max(fluid.comm, X)
    np.testing.assert_allclose(x[cap, :2], X[cap, :2] + bump(A)(X[cap].T).T, rtol=0, atol=last_bits)
    still = np.setdiff1d(
        boundary_nodes(fluid, Boundary.INLET, Boundary.OUTLET, Boundary.RIGID_WALL), cap
    )
    assert np.array_equal(x[still], X[still])
    # The apex moved by A and the interior followed (by less than A, more than nothing).
    assert np.isclose(global_max(fluid.comm, x[cap, 1] - X[cap, 1]), A, rtol=1e-6)
    interior = np.setdiff1d(np.arange(len(x)), boundary_nodes(fluid, *FLUID_BOUNDARIES))
    moved = global_max(fluid.comm, x[interior, 1] - X[interior, 1])
    assert 0.5 * A < moved < A
    # The smallest cell ratio is in the big, soft cells at the opposite wall (x, y) ≈ (10.3,
    # 6.9) mm; measured on 1 and 2 ranks, dolfinx 0.5 and 0.9: 0.7861.
    assert mm.check_quality() == pytest.approx(0.7861, abs=1e-4)


def test_boundary_data_from_the_solid_through_a_p2_interface_map(fluid):
    """The coupler's path: the solid's P2 displacement → the fluid's P2 space on Γw1
    (fsi.coupled.interface.InterfaceMap) → MeshMotion.set_boundary_function, which takes its vertex
    values: the same data as setting the interface vector directly."""
    import dolfinx.fem

    from fsi.coupled.interface import InterfaceMap
    from fsi.geometry.tags import STRUCTURE_REGIONS

    solid = mesh.restrict(mesh.build(CASE), *STRUCTURE_REGIONS)
    V_s = compat.function_space(solid.mesh, "Lagrange", 2, (2,))
    V_f = compat.function_space(fluid.mesh, "Lagrange", 2, (2,))
    imap = InterfaceMap(
        V_s, solid.facets(Boundary.INTERFACE), V_f, fluid.facets(Boundary.INTERFACE)
    )
    eta, on_fluid = dolfinx.fem.Function(V_s), dolfinx.fem.Function(V_f)
    eta.interpolate(bump(3e-4))
    imap.set_dst(on_fluid, imap.transfer(support_physics.src_vector(imap, eta)))

    mm = MeshMotion(fluid)
    mm.set_boundary_function(on_fluid)
    from_function = support_physics.boundary_vector(mm, mm.g)
    expected = bump(3e-4)(mm.interface_points.T).T
    # P2 → P1 is evaluation at the vertices, where the P2 function has its nodal values: exact
    # to round-off (1e-15 m is 3e-12 of the 0.3 mm amplitude).
    assert global_max(fluid.comm, from_function - expected) < 1e-15
    assert fluid.comm.allreduce(len(mm.interface_dofs)) > 50


@pytest.mark.parametrize("stiffening, expected", [("jacobian", 0.1442), ("distance", 0.1296)])
def test_stiffening_keeps_cells_from_inverting(fluid, stiffening, expected):
    """A 2 mm bump (57 % of the apex gap) inverts cells of the unstiffened harmonic extension
    (min J/J_ref = −0.127); stiffening small cells, or cells near the interface, keeps them
    positive. The same numbers on any number of ranks: compared with a serial solve."""
    f = bump(2e-3)

    def min_ratio(tagged, kind):
        mm = MeshMotion(tagged, mesh_motion_settings(stiffening=kind, stiffening_exponent=1.0))
        support_physics.set_boundary_displacement(mm, f(mm.interface_points.T).T)
        mm.solve()
        return mm.min_jacobian_ratio()[0]

    plain, stiff = min_ratio(fluid, "none"), min_ratio(fluid, stiffening)
    assert plain < 0 < stiff
    # Measured on the coarse default mesh (1 and 2 ranks, dolfinx 0.5 and 0.9): 4 digits.
    assert plain == pytest.approx(-0.1273, abs=1e-4)
    assert stiff == pytest.approx(expected, abs=1e-4)
    serial = fluid_submesh(MPI.COMM_SELF)
    # Same mesh (gmsh is deterministic), other partition: equal to solver round-off.
    assert min_ratio(serial, "none") == pytest.approx(plain, abs=1e-10)
    assert min_ratio(serial, stiffening) == pytest.approx(stiff, abs=1e-10)


def test_quality_guard(fluid):
    mm = MeshMotion(fluid)
    # Small: 0.1 mm, cells barely change.
    support_physics.set_boundary_displacement(mm, bump(1e-4)(mm.interface_points.T).T)
    mm.solve()
    assert mm.check_quality() == pytest.approx(0.9572, abs=1e-4)

    # 4 mm through a 3.5 mm gap: the plaque passes the opposite wall, cells must invert.
    reference = fluid.mesh.geometry.x.copy()
    support_physics.set_boundary_displacement(mm, bump(4e-3)(mm.interface_points.T).T)
    mm.solve()
    with pytest.raises(MeshQualityError) as info:
        mm.check_quality()
    e = info.value
    assert e.ratio < 0 and e.threshold == 0.05 and "inverted" in str(e)
    assert X0 < e.where[0] < X0 + LS  # above the plaque
    # The guard judges X + d without moving the mesh, so the coupler runs it before the
    # fluid's AleMesh moves the mesh: the fluid never sees the inverted mesh.
    assert np.array_equal(fluid.mesh.geometry.x, reference)

    # Not inverted but below a strict threshold: 1 mm unstiffened gives min J/J_ref = 0.436.
    strict = MeshMotion(fluid, mesh_motion_settings(stiffening="none", min_jacobian_ratio=0.5))
    support_physics.set_boundary_displacement(strict, bump(1e-3)(strict.interface_points.T).T)
    strict.solve()
    with pytest.raises(MeshQualityError, match="collapsed") as info:
        strict.check_quality()
    assert info.value.ratio == pytest.approx(0.4364, abs=1e-4)


@pytest.mark.parametrize("method", ["harmonic", "elastic"])
def test_mesh_velocity_of_a_linear_motion(fluid, method):
    """d(t) = t f: the extension is linear in the data, so d(t) = t E(f) and both backward Euler
    and variable-step BDF2 give the AleMesh's w = E(f) exactly; on the interface w = f."""
    f = bump(3e-4)
    mm = MeshMotion(fluid, mesh_motion_settings(method=method))
    ale = AleMesh(fluid.mesh)
    values = f(mm.interface_points.T).T
    support_physics.set_boundary_displacement(mm, values)
    extension = mm.solve().x.array.copy()

    times = [0.3, 0.5, 0.6]  # dt = 0.2, then 0.1
    for i, t in enumerate(times):
        support_physics.set_boundary_displacement(mm, t * values)
        ale.move(mm.solve())
        if i == 1:
            ale.set_velocity(bdf_weights(1, 0.2))
        elif i == 2:
            ale.set_velocity(bdf_weights(2, 0.1, dt_previous=0.2))
        if i:
            w = ale.w.x.array
            # Round-off of d (~1e-16 |d|) divided by dt: far below 1e-10 relative.
            scale = global_max(fluid.comm, extension)
            assert global_max(fluid.comm, w - extension) < 1e-10 * scale
            on_interface = w.reshape(-1, 2)[mm.interface_dofs]
            assert global_max(fluid.comm, on_interface - values) < 1e-12 * scale
        ale.advance()


def test_solve_reuses_the_matrix_and_its_factorisation(fluid):
    """Twenty solves, one assembly and one LU factorisation (counted by PETSc's event log)."""
    PETSc.Log.begin()
    numeric = PETSc.Log.Event("MatLUFactorNum")
    before = numeric.getPerfInfo()["count"]
    mm = MeshMotion(fluid, mesh_motion_settings(method="elastic"))
    assert mm._ksp.getOptionsPrefix() == "mesh_"
    assert mm._ksp.getPC().getType() == "lu"
    values = bump(1e-4)(mm.interface_points.T).T
    for i in range(1, 21):
        support_physics.set_boundary_displacement(mm, i * values)
        mm.solve()
        if i == 1:
            first = mm.d.x.array.copy()
    assert mm.assemblies == 1
    assert numeric.getPerfInfo()["count"] - before == 1
    # The reused factorisation still solves correctly: the extension is linear in the data.
    scale = global_max(fluid.comm, 20 * first)
    assert global_max(fluid.comm, mm.d.x.array - 20 * first) < 1e-12 * scale
    # The config's options were read, then removed from PETSc's global database.
    assert not PETSc.Options().hasName("mesh_pc_type")


def test_iterative_solver_from_the_config(fluid):
    """petsc_options reach the mesh_ solver: CG + Jacobi gives the LU answer."""
    values = None
    results = []
    for options in (
        {},
        {
            "petsc_options": {
                "ksp_type": "cg",
                "pc_type": "jacobi",
                "ksp_rtol": 1e-12,
                "ksp_max_it": 5000,
            }
        },
    ):
        mm = MeshMotion(fluid, mesh_motion_settings(**options))
        values = bump(2e-4)(mm.interface_points.T).T if values is None else values
        support_physics.set_boundary_displacement(mm, values)
        results.append(mm.solve().x.array.copy())
        assert mm._ksp.getType() == ("cg" if options else "preonly")
    # CG stops at rtol 1e-12 on the preconditioned residual: ~1e-9 in d is ample.
    assert global_max(fluid.comm, results[1] - results[0]) < 1e-8 * global_max(
        fluid.comm, results[0]
    )


def test_ale_mesh_moves_resets_and_restores(fluid):
    """AleMesh moves the mesh to X + d, back to X with d = 0, and its restore brings back d,
    its history and the mesh position."""
    mm = MeshMotion(fluid)
    ale = AleMesh(fluid.mesh)
    reference = fluid.mesh.geometry.x.copy()
    support_physics.set_boundary_displacement(mm, bump(3e-4)(mm.interface_points.T).T)
    ale.move(mm.solve())
    ale.advance()
    state = ale.save()
    moved = fluid.mesh.geometry.x.copy()
    assert global_max(fluid.comm, moved - reference) > 1e-4
    ale.move(dolfinx.fem.Function(ale.space))
    assert np.array_equal(fluid.mesh.geometry.x, reference)

    support_physics.set_boundary_displacement(mm, bump(-3e-4)(mm.interface_points.T).T)
    ale.move(mm.solve())
    ale.advance()
    ale.restore(*state)
    d, d_n, _, _ = state
    assert np.array_equal(ale.d.x.array, d) and np.array_equal(ale.history.x_n, d_n)
    assert np.array_equal(fluid.mesh.geometry.x, moved)  # restore moves the mesh back, too


def test_config_section():
    s = CASE.mesh_motion
    assert (s.method, s.stiffening, s.min_jacobian_ratio) == ("harmonic", "jacobian", 0.05)
    with pytest.raises(config.ConfigError, match="mesh_motion.min_jacobian_ratio"):
        mesh_motion_settings(min_jacobian_ratio=1.0)
    with pytest.raises(config.ConfigError, match="mesh_motion.stiffening"):
        mesh_motion_settings(stiffening="laplace")
