"""Coupled 3D runs through ``fsi run`` (issue #44; docs/3d.md): the elastic-tube pulse's case as
tetrahedra (R 5 mm, h 1 mm, 15 mm long, 2 mm cells), blood and wall coupled (the fluid's
forms, the mesh motion and the interface transfer in 3D): it runs, the wall moves outward under
the pulse, a restart continues exactly, 1 and 2 ranks agree, and the outputs have their 3D
meaning (wall_indices.csv with z, the vector τ's indices). The 3D wall shear stress samples and
their indices are checked against closed forms here too."""

from __future__ import annotations

import csv
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from test_restart import assert_same_rows, differences, fsi_run

from fsi import config
from fsi.output import metrics_csv, wall_indices
from fsi.run import simulation

PULSE = "configs/axisymmetric/tube_pulse.yaml"
TUBE_3D = [
    "geometry.dimension=3",
    "geometry.axisymmetric=false",
    "geometry.length=0.015",
    "mesh.size=2.0e-3",
    "mesh.local_size=2.0e-3",
    "output.checkpoint_every=1",
    "time.schedule=[{until: 2.0e-4, dt: 1.0e-4}]",
]


@pytest.fixture(scope="module")
def pulse_runs():
    """2 steps straight; 1 step, then a restart to 2."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    straight, first, second = (path / n for n in ("straight", "first", "second"))
    codes = [
        fsi_run(PULSE, straight, [*TUBE_3D, "time.end=2.0e-4"]),
        fsi_run(PULSE, first, [*TUBE_3D, "time.end=1.0e-4"]),
    ]
    codes.append(fsi_run(PULSE, second, [*TUBE_3D, "time.end=2.0e-4"], restart=first))
    yield {"codes": codes, "straight": straight, "second": second}
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def test_the_3d_tube_couples_its_wall_to_the_pulse(pulse_runs):
    """The coupling converges in both steps (IQN-ILS, 1e-6), the wall at A moves outward by
    about what Lamé's cylinder gives for the inlet's pressure (the pulse has not left the
    tube's first half yet: between 5 % and 100 % of it), the blood flows in (m³/s), and
    wall_indices.csv has a z column and a row per wall sample."""
    assert pulse_runs["codes"] == [0, 0, 0]
    found = metrics_csv.read_metrics(pulse_runs["straight"] / "metrics.csv")
    assert len(found) == 2
    last = found[-1]
    assert last["coupling_iterations"] < 100 and last["coupling_residual"] < 1e-6
    p, a, b, E, nu = 1333.2, 0.005, 0.006, 3.0e5, 0.3
    lame = p * a * (1 + nu) / E * ((1 - 2 * nu) * a * a / (b * b - a * a) + b * b / (b * b - a * a))
    assert 0 < last["peak_displacement"] < lame
    assert last["inlet_flow_rate"] > 0 and last["inlet_flow_rate"] < np.pi * a**2
    with open(pulse_runs["straight"] / "wall_indices.csv") as f:
        table = list(csv.DictReader(f))
    assert list(table[0])[:5] == ["wall", "side", "x", "y", "z"]
    radii = np.hypot([float(r["y"]) for r in table], [float(r["z"]) for r in table])
    assert np.allclose(radii, a, rtol=0.05)  # the samples lie on the lumen's surface
    osi = np.array([float(r["OSI"]) for r in table])
    assert np.all((osi >= 0) & (osi <= 0.5))


def test_a_coupled_3d_run_restarts_exactly(pulse_runs):
    """The restarted run's rows and final state are the uninterrupted run's: bit for bit on 1
    rank; on 2, as the axisymmetric runs (test_axisymmetric_coupled): the solution's arrays to
    1e-9, the IQN-ILS secant columns to 1e-7."""
    assert pulse_runs["codes"] == [0, 0, 0]
    assert_same_rows(pulse_runs["second"], pulse_runs["straight"])
    serial = MPI.COMM_WORLD.size == 1
    for key, difference in differences(pulse_runs["second"], pulse_runs["straight"]).items():
        bound = 0.0 if serial else 1e-7 if key.startswith("coupling.iqn.") else 1e-9
        assert difference <= bound, (key, difference)


def test_serial_and_parallel_3d_runs_agree(pulse_runs, shared_tmp):
    """The same 2 steps on every rank alone and on all ranks: peaks and point A's displacement
    to 1e-6 relative (the coupling tolerance is 1e-6)."""
    comm = MPI.COMM_WORLD
    if comm.size == 1:
        pytest.skip("compares 1 rank with this run's ranks: meaningful on 2 or more")
    alone = shared_tmp / f"alone{comm.rank}"
    case = config.load(PULSE, [*TUBE_3D, "time.end=2.0e-4"])
    simulation.run(case, alone, MPI.COMM_SELF)
    world = metrics_csv.read_metrics(pulse_runs["straight"] / "metrics.csv")
    self_rows = metrics_csv.read_metrics(alone / "metrics.csv")
    assert len(world) == len(self_rows) == 2
    for a, b in zip(world, self_rows):
        for key in ("peak_velocity", "peak_pressure", "peak_displacement", "ur_A", "max_wss"):
            assert a[key] == pytest.approx(b[key], rel=1e-6), key


def test_vector_indices_of_a_rotating_and_a_reversing_shear():
    """The 3D indices average the vector τ: a shear of constant magnitude 2 Pa turning through
    a full circle in the wall's plane has TAWSS 2 and OSI ½ (its mean vanishes), though each
    component alone would give OSI ½ as well but TAWSS 4/π; a constant one OSI 0; a shear
    reversing linearly, τ(t) = (1 − 2t) e over [0, 1], TAWSS ½ exactly but Simpson's 1/3 (the
    documented kink error, |a|/6)."""
    steps = 720
    indices = wall_indices.WallIndices(3, components=3)
    indices.set_value(np.array([[0.0, 2.0, 0.0], [1.0, 1.0, 1.0], [1.0, 0.0, 0.0]]))
    for k in range(1, steps + 1):
        t = k / steps
        turning = [0.0, 2 * np.cos(2 * np.pi * t), 2 * np.sin(2 * np.pi * t)]
        indices.add(t, np.array([turning, [1.0, 1.0, 1.0], [1 - 2 * t, 0.0, 0.0]]))
    assert indices.tawss[0] == pytest.approx(2.0, rel=1e-5)
    assert indices.osi[0] == pytest.approx(0.5, abs=1e-6)
    assert indices.tawss[1] == pytest.approx(np.sqrt(3), rel=1e-12) and indices.osi[1] < 1e-12
    assert indices.tawss[2] == pytest.approx(0.5, rel=1e-5)  # many small steps: no kink error
    one = wall_indices.WallIndices(1, components=3)
    one.set_value(np.array([[1.0, 0.0, 0.0]]))
    one.add(1.0, np.array([[-1.0, 0.0, 0.0]]))
    assert one.tawss[0] == pytest.approx(1 / 3, rel=1e-12)
    with pytest.raises(ValueError, match="of 3 components"):
        one.add(2.0, np.zeros(1))


def _cube_snapshot(center: str = "node"):
    """A unit cube of 2 × 2 × 2 × 6 tetrahedra carrying f = x + 2y + 3z (per node, or per cell
    at its centroid) as a :class:`fsi.output.plot.Snapshot`."""
    import dolfinx.mesh

    from fsi import compat
    from fsi.output.field_files import Snapshot

    cube = dolfinx.mesh.create_unit_cube(MPI.COMM_SELF, 2, 2, 2)
    x = cube.geometry.x
    tets = compat.geometry_dofmap(cube).astype(np.int64)
    f = x @ np.array([1.0, 2.0, 3.0])
    values = f if center == "node" else f[tets].mean(axis=1)
    return Snapshot(
        Path("."),
        "pressure",
        "fluid",
        Path("fields.xdmf"),
        0.0,
        0.0,
        0.0,
        center,
        x,
        None,
        0.0,
        tets,
        np.arange(len(tets)),
        values,
        None,
    )


@pytest.mark.parametrize("text", ["z=0.3", "z=0.5", "x=0", "y=1"])
def test_a_section_of_tetrahedra_is_the_plane_s_polygon_with_exact_linear_values(text):
    """The cube's section by a plane between nodes (z = 0.3), through a layer of nodes and
    faces (z = 0.5) and on its faces (x = 0, y = 1): triangles covering the unit square once
    (area 1), every point on the plane, a linear node field exact at every new node, a cell
    field its parent's value."""
    from fsi.output import section

    plane = section.Plane.parse(text)
    cut = section.cut(_cube_snapshot(), plane)
    xy = cut.reference
    a, b, c = (xy[cut.triangles[:, k]] for k in range(3))
    areas = 0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    assert areas.sum() == pytest.approx(1.0, rel=1e-12) and areas.min() > 0
    assert len(np.unique(np.round(xy, 12), axis=0)) == len(xy)  # no point twice
    point = np.zeros((len(xy), 3))
    point[:, list(plane.in_plane)] = xy
    point[:, plane.axis] = plane.value
    assert np.allclose(cut.values, point @ np.array([1.0, 2.0, 3.0]), rtol=0, atol=1e-12)
    cells = section.cut(_cube_snapshot("cell"), plane)
    assert len(cells.values) == len(cells.triangles)


def test_a_section_refuses_a_bad_plane():
    from fsi.output import section
    from fsi.output.field_files import PlotError

    for text in ("w=0", "x", "y=abc", "z=inf"):
        with pytest.raises(PlotError, match="--slice"):
            section.Plane.parse(text)
    with pytest.raises(PlotError, match="misses"):
        section.cut(_cube_snapshot(), section.Plane.parse("z=2"))


def test_fsi_plot_draws_sections_and_the_unrolled_wall(pulse_runs, shared_tmp, capsys):
    """``fsi plot`` of the 3D run: a field's section through the axis (with streamlines) and
    across it, the TAWSS map on the unrolled wall; a 3D field without --slice exits 2 naming
    the option."""
    from fsi import cli

    run = str(pulse_runs["straight"])
    for field, more in (
        ("velocity", ["--slice", "z=0", "--streamlines"]),
        ("von_mises", ["--slice", "x=0.01"]),
        ("tawss", []),
    ):
        out = shared_tmp / f"{field}.png"
        time = [] if field == "tawss" else ["--time", "2e-4"]
        assert cli.main(["plot", run, "--field", field, *time, *more, "--out", str(out)]) == 0
        if MPI.COMM_WORLD.rank == 0:
            assert out.stat().st_size > 10_000
    bad = ["plot", run, "--field", "pressure", "--time", "2e-4", "--out", str(shared_tmp / "p.png")]
    assert cli.main(bad) == 2
    if MPI.COMM_WORLD.rank == 0:
        assert "--slice" in capsys.readouterr().err


@pytest.mark.parametrize("method", ["harmonic", "elastic"])
def test_the_gamg_preset_moves_the_3d_mesh_as_lu_does(method):
    """The mesh motion of the 3D tube's lumen under a radial interface displacement: CG + GAMG
    (the rigid-body near-nullspace on its matrix) gives MUMPS's extension to 1e-8."""
    from fsi.geometry.tags import Boundary, Region
    from fsi.physics import mesh
    from fsi.physics.mesh_motion import MeshMotion

    case = config.load(PULSE, [*TUBE_3D, "time.end=2.0e-4"])
    fluid = mesh.restrict(mesh.build(case, MPI.COMM_WORLD), Region.FLUID)
    gamg = {"ksp_type": "cg", "pc_type": "gamg", "ksp_rtol": 1e-12, "ksp_max_it": 1000}
    found = []
    for options in ({}, gamg):
        settings = config.MeshMotionSettings(
            method=method, **({"petsc_options": options} if options else {})
        )
        motion = MeshMotion(fluid, settings, moving=(Boundary.INTERFACE,))
        motion.set_boundary_function(
            lambda x: np.vstack([0 * x[0], 1e-4 * x[1] * x[0], 1e-4 * x[2] * x[0]])
        )
        found.append(motion.solve().x.array.copy())
    scale = MPI.COMM_WORLD.allreduce(float(np.abs(found[0]).max(initial=0.0)), op=MPI.MAX)
    worst = MPI.COMM_WORLD.allreduce(
        float(np.abs(found[1] - found[0]).max(initial=0.0)), op=MPI.MAX
    )
    assert scale > 0 and worst < 1e-8 * scale, worst / scale


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        ({"pc_type": "gamgx"}, "not a preconditioner type of the installed PETSc"),
        ({"ksp_type": "cgx"}, "not a Krylov solver type"),
        ({"pc_factor_mat_solver_type": "pastix"}, "needs PETSc built with pastix"),
        ({"pc_factor_mat_solver_type": "nosuch"}, "not a factorisation package"),
    ],
)
def test_a_solver_preset_the_installed_petsc_lacks_is_refused(options, expected):
    """A preset naming a type or package the installed PETSc does not have is refused before
    any solve, naming the key (Debian's PETSc has MUMPS, SuperLU_dist, hypre, ML and GAMG, not
    PaStiX)."""
    with pytest.raises(config.ConfigError, match=expected) as refused:
        config.from_dict({"structure": {"solver": {"petsc_options": options}}})
    assert refused.value.key.startswith("structure.solver.petsc_options.")
