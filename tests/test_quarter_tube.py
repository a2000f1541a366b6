"""The quarter of a 3D tube (``geometry.sector: 90``; geometry/vessel_3d.py, docs/3d.md): the
part y >= 0, z >= 0 of a problem that is mirror-symmetric about the planes y = 0 and z = 0 (a
tube under pressure, solids4foam's 3dTube), with the normal components of the blood's velocity,
the wall's displacement and the mesh motion held at 0 on the two cuts, which carry no tag (so
no traction, no tissue support and no mesh clamp acts there).

Checked: the mesh (its tags, volumes and areas a quarter of the whole's), Lamé's thick cylinder
and Poiseuille's flow on the quarter against their exact solutions at the whole tube's
tolerances, and a few coupled steps of the pressure pulse (the cuts keep their normal
components at 0 while the mesh slides along them, and point A moves as in the whole tube).
"""

from __future__ import annotations

import math
from dataclasses import replace

from mpi4py import MPI

import numpy as np
import pytest

from fsi import config
from fsi.config import Material, SolverSettings
from fsi.config.reader import ConfigError
from fsi.geometry import vessel_3d
from fsi.geometry.tags import Boundary, Region
from fsi.numerics.timestepping import NewmarkFamily, steps
from fsi.output.wall_outputs import FluidOutputs
from fsi.physics import fluid, fluid_case, mesh, mesh_3d, solid
from fsi.physics.solid_boundaries import Clamp, Roller
from fsi.physics.solid_boundaries import boundary_conditions as solid_boundary_conditions
from fsi.run import steppers

PULSE = "configs/3d/tube_pulse.yaml"


def tube(sector: int, size: float, **geometry) -> config.Case:
    return config.from_dict(
        {
            "geometry": {
                "kind": "tube",
                "dimension": 3,
                "axisymmetric": False,
                "sector": sector,
                **geometry,
            },
            "mesh": {"size": size, "local_size": size},
            "structure": {"mode": "moving_wall"},
        }
    )


# --------------------------------------------------------------------------------------------
# The mesh and the refusals


def test_the_quarter_is_a_quarter_with_untagged_cuts():
    """Volumes, the lumen's and the exterior's areas a quarter of the whole tube's (the
    inscribed polygon's deficit of ~h²/(6R²) aside: within 1 %), the same tags, and no face of
    the cuts tagged (the exterior's area is the curved surface's alone)."""
    case = tube(90, 1e-3)
    g = case.geometry
    R, t, L = g.radius, g.wall_thickness, g.length
    whole = vessel_3d.analytic_volumes(tube(360, 1e-3).geometry)
    exact = vessel_3d.analytic_volumes(g)
    assert exact["fluid"] == pytest.approx(whole["fluid"] / 4, rel=1e-14)
    assert vessel_3d.interface_area(g) == pytest.approx(math.pi / 2 * R * L, rel=1e-14)
    tagged = mesh.build(case, MPI.COMM_WORLD)
    volumes = mesh_3d.region_volumes(tagged, (Region.FLUID, Region.WALL))
    assert volumes["fluid"] == pytest.approx(exact["fluid"], rel=1e-2)
    assert volumes["wall"] == pytest.approx(exact["wall"], rel=1e-2)

    def area(boundary: Boundary) -> float:
        triangles = mesh_3d.facet_triangles(tagged, boundary)
        cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        return float(np.linalg.norm(cross, axis=1).sum() / 2)

    assert area(Boundary.EXTERIOR) == pytest.approx(math.pi / 2 * (R + t) * L, rel=1e-2)
    assert area(Boundary.INTERFACE) == pytest.approx(math.pi / 2 * R * L, rel=1e-2)
    assert area(Boundary.INLET) == pytest.approx(math.pi / 4 * R**2, rel=1e-2)
    # every tagged face lies off the cuts but the interface's, clamp's and inlet's edges
    for boundary in (Boundary.EXTERIOR, Boundary.INLET, Boundary.CLAMPED, Boundary.INTERFACE):
        centroids = mesh_3d.facet_triangles(tagged, boundary).mean(axis=1)
        assert centroids[:, 1:].min() > 0, boundary
    assert config.symmetry_planes(g) == (1, 2)
    assert config.symmetry_planes(tube(360, 1e-3).geometry) == ()


@pytest.mark.parametrize(
    "overrides, key",
    [
        (["geometry.sector=45"], "geometry.sector"),
        (["geometry.dimension=2", "geometry.axisymmetric=true"], "geometry.sector"),
        (["fluid.inlet={kind: flow_rate, formula: '1e-6'}"], "fluid.inlet.kind"),
    ],
)
def test_a_quarter_that_cannot_be_is_refused(overrides, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        config.load(PULSE, ["geometry.sector=90", *overrides])


# --------------------------------------------------------------------------------------------
# Exact solutions on the quarter

PRESSURE, YOUNG, POISSON = 1000.0, 1.0e6, 0.3


def test_lames_cylinder_on_the_quarter():
    """The quarter wall (a 5 mm, b 6 mm, 0.4 mm cells; roller ends, the case's symmetry
    planes, 1 kPa inside, quasi-static): u_r on the inner surface within 1 % of Lamé's at every
    node, as the whole tube's test (tests/test_solid_3d.py)."""
    case = tube(90, 4e-4, length=0.004, radius=0.005, wall_thickness=0.001)
    domain = solid.structure_mesh(mesh.build(case, MPI.COMM_WORLD), (Region.WALL,))
    conditions = solid_boundary_conditions(case, lambda t: PRESSURE)
    # the case's clamp → a roller: plane strain, as Lamé's
    dirichlet = tuple(
        Roller((Boundary.CLAMPED,), component=0) if isinstance(d, Clamp) else d
        for d in conditions.dirichlet
    )
    s = solid.SolidSolver(
        domain,
        {Region.WALL: Material(density=1000.0, young_modulus=YOUNG, poisson_ratio=POISSON)},
        replace(conditions, dirichlet=dirichlet),
        NewmarkFamily.quasi_static(),
        solver=SolverSettings(rtol=1e-10, atol=1e-15, max_iterations=20),
    )
    assert s.step(1.0, 1.0).converged
    a, b = 0.005, 0.006
    u, x = s.interface_displacement(), s.interface_points
    r = np.hypot(x[:, 1], x[:, 2])
    A = PRESSURE * a**2 / (b**2 - a**2)
    u_lame = (1 + POISSON) / YOUNG * ((1 - 2 * POISSON) * A * r + A * b**2 / r)
    u_r = (u[:, 1] * x[:, 1] + u[:, 2] * x[:, 2]) / r
    worst = s.comm.allreduce(float(np.abs(u_r / u_lame - 1).max(initial=0.0)), op=MPI.MAX)
    assert worst < 0.01
    # the cuts: no normal displacement, the radial one free
    on_y0 = np.abs(x[:, 1]) < 1e-9
    assert np.all(u[on_y0, 1] == 0) and np.all(u[np.abs(x[:, 2]) < 1e-9, 2] == 0)


def test_poiseuilles_flow_on_the_quarter():
    """A steady pressure drop G L across the rigid quarter pipe (R 2 mm, L 4 mm, 0.3 mm cells,
    ρ = 1 as the whole pipe's test): four times the inlet's flow rate within 1 % of
    π R⁴ G/(8 μ), and the velocity's normal components 0 on the cuts."""
    mu, G, L, R = 0.0035, 2500.0, 0.004, 0.002
    case = config.from_dict(
        {
            "geometry": {
                "kind": "tube",
                "dimension": 3,
                "axisymmetric": False,
                "sector": 90,
                "length": L,
                "radius": R,
                "wall_thickness": 5e-4,
            },
            "structure": {"mode": "rigid"},
            "mesh": {"size": 3e-4, "local_size": 3e-4},
            "fluid": {
                "density": 1.0,
                "rheology": {"model": "newtonian", "viscosity": mu},
                "solver": {"rtol": 1e-20, "atol": 1e-12},
                "inlet": {"kind": "pressure", "formula": repr(G * L)},
            },
        }
    )
    part = mesh.restrict(mesh.build(case, MPI.COMM_WORLD), Region.FLUID)
    solver = fluid.FluidSolver(
        part.mesh, part.facet_tags, case.fluid, fluid_case.fluid_conditions(case), "steady"
    )
    assert solver.step(1.0, 1.0).converged
    row = FluidOutputs(case, solver).update()
    exact = math.pi * R**4 * G / (8 * mu)
    assert 4 * row["inlet_flow_rate"] == pytest.approx(exact, rel=1e-2)
    assert 4 * row["outlet_flow_rate"] == pytest.approx(exact, rel=1e-2)
    owned = solver.V.dofmap.index_map.size_local  # (a submesh's orphan ghosts sit at 0, 0, 0)
    x = solver.V.tabulate_dof_coordinates()[:owned]
    u = solver.u.x.array.reshape(-1, 3)[:owned]
    assert np.all(u[np.abs(x[:, 1]) < 1e-12, 1] == 0)
    assert np.all(u[np.abs(x[:, 2]) < 1e-12, 2] == 0)


# --------------------------------------------------------------------------------------------
# The pressure pulse on the quarter


def test_the_pulse_on_the_quarter_slides_along_its_cuts():
    """Four steps of configs/3d/tube_pulse.yaml on the quarter (2 mm cells): the blood's and
    the mesh's normal components are 0 on the cuts while the mesh moves radially along them with
    the wall, and point A (on the cut z = 0) moves outwards."""
    case = config.load(
        PULSE,
        ["geometry.sector=90", "mesh.size=2e-3", "mesh.local_size=2e-3", "time.end=1e-4"],
    )
    stepper = steppers.CoupledStepper(case, MPI.COMM_WORLD)
    rows = [stepper.step(step) for step in steps(case.time)]
    assert [r["ur_A"] > 0 for r in rows] == [True] * 4
    problem = stepper.problem
    f = problem.fluid
    owned = f.V.dofmap.index_map.size_local  # (a submesh's orphan ghosts sit at 0, 0, 0)
    x = f.V.tabulate_dof_coordinates()[:owned]
    u = f.u.x.array.reshape(-1, 3)[:owned]
    speed = rows[-1]["peak_velocity"]
    # 0 but where the wall's velocity wins at the cuts' edges (its round-off: ~1e-19 m/s)
    assert np.abs(u[np.abs(x[:, 1]) < 1e-12, 1]).max(initial=0) <= 1e-12 * speed
    assert np.abs(u[np.abs(x[:, 2]) < 1e-12, 2]).max(initial=0) <= 1e-12 * speed
    owned = problem.motion.V.dofmap.index_map.size_local
    d = problem.motion.d.x.array.reshape(-1, 3)[:owned]
    X = problem.motion.dof_points[:owned]
    on_z0 = np.abs(X[:, 2]) < 1e-12
    assert np.abs(d[on_z0, 2]).max(initial=0) <= 1e-12 * rows[-1]["ur_A"]
    radial = MPI.COMM_WORLD.allreduce(float(np.abs(d[on_z0, 1]).max(initial=0.0)), op=MPI.MAX)
    assert radial > 0.1 * rows[-1]["ur_A"]  # the cut's nodes slide with the wall
