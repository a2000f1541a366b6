"""Submesh tags and the fluid <-> solid interface transfer, on any number of ranks."""

from mpi4py import MPI

import numpy as np
import pytest
import support_physics

from fsi import compat, config
from fsi.coupled import interface
from fsi.geometry.tags import STRUCTURE_REGIONS, Boundary, Region
from fsi.physics import mesh


@pytest.fixture(scope="module")
def parts():
    case = config.from_dict({})
    tagged = mesh.build(case)
    return tagged, mesh.restrict(tagged, Region.FLUID), mesh.restrict(tagged, *STRUCTURE_REGIONS)


def _owned_count(t: mesh.TaggedMesh, boundary: Boundary) -> int:
    facets = t.facets(boundary)
    n = np.count_nonzero(facets < t.mesh.topology.index_map(1).size_local)
    return t.comm.allreduce(int(n))


def test_submeshes_carry_the_tags(parts):
    whole, fluid, solid = parts
    interface_facets = _owned_count(whole, Boundary.INTERFACE)
    assert _owned_count(fluid, Boundary.INTERFACE) == interface_facets
    assert _owned_count(solid, Boundary.INTERFACE) == interface_facets
    for b in (Boundary.INLET, Boundary.OUTLET, Boundary.RIGID_WALL):
        assert _owned_count(fluid, b) == _owned_count(whole, b) > 0
        assert _owned_count(solid, b) == 0
    for b in (Boundary.CLAMPED, Boundary.EXTERIOR, Boundary.CAP_LIPID, Boundary.PLAQUE_BASE):
        assert _owned_count(solid, b) == _owned_count(whole, b) > 0
    solid_regions = set(np.concatenate(whole.comm.allgather(solid.cell_tags.values)))
    assert solid_regions == {int(r) for r in STRUCTURE_REGIONS}


@pytest.mark.parametrize("degree", [1, 2])
def test_solid_to_fluid_transfer_is_exact_at_the_interface(parts, degree):
    _, fluid, solid = parts
    V_s = compat.function_space(solid.mesh, "Lagrange", degree, (2,))
    V_f = compat.function_space(fluid.mesh, "Lagrange", degree, (2,))
    imap = interface.InterfaceMap(
        V_s, solid.facets(Boundary.INTERFACE), V_f, fluid.facets(Boundary.INTERFACE)
    )

    def field(x):
        return np.vstack([np.sin(300 * x[0]) + x[1], np.cos(200 * x[1]) * x[0]])

    import dolfinx.fem

    eta, u = dolfinx.fem.Function(V_s), dolfinx.fem.Function(V_f)
    eta.interpolate(field)
    imap.set_dst(u, imap.transfer(support_physics.src_vector(imap, eta)))
    points = V_f.tabulate_dof_coordinates()[imap.dst_dofs]
    expected = field(points.T).T
    assert np.abs(u.x.array.reshape(-1, 2)[imap.dst_dofs] - expected).max(initial=0.0) < 1e-12
    # Every interface node once: owned counts add up to the same total on both sides.
    comm = MPI.COMM_WORLD
    assert comm.allreduce(len(imap.src_dofs)) == comm.allreduce(len(imap.dst_dofs)) == imap.size
    # The interface polyline with P2 has 2 nodes per facet plus one.
    n_facets = _owned_count(fluid, Boundary.INTERFACE)
    assert imap.size == degree * n_facets + 1


def test_non_conforming_spaces_are_refused(parts):
    _, fluid, solid = parts
    V_s = compat.function_space(solid.mesh, "Lagrange", 2, (2,))
    V_f = compat.function_space(fluid.mesh, "Lagrange", 1, (2,))
    with pytest.raises(ValueError, match="interface dof counts differ"):
        interface.InterfaceMap(
            V_s, solid.facets(Boundary.INTERFACE), V_f, fluid.facets(Boundary.INTERFACE)
        )
