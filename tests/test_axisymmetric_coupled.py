"""Coupled axisymmetric runs through ``fsi run`` (issue #28; docs/axisymmetric.md): the tube's
wall under a static pressure against Lamé, a restart that continues exactly, and 1 and 2 ranks
alike, on the elastic-tube pulse's case made coarse, and the axisymmetric stenosis's moving
wall."""

import math
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import pytest
from test_restart import assert_same_rows, differences, fsi_run, rows

from fsi import config
from fsi.output import metrics_csv
from fsi.run import simulation

PULSE = "configs/axisymmetric/tube_pulse.yaml"
COARSE = ["mesh.size=1.0e-3", "mesh.local_size=1.0e-3", "output.checkpoint_every=1"]
STEPS = "time.schedule=[{until: 2.0e-4, dt: 1.0e-4}]"


def test_the_tube_widens_as_lames_cylinder_under_a_static_pressure(shared_tmp):
    """The pulse's tube (R 5 mm, h 1 mm, E 0.3 MPa, ν 0.3) loaded by a follower pressure of
    100 Pa on its inner wall alone (``interface_load: inlet_pressure``, quasi-static, one step):
    the radial displacement at mid-length is Lamé's for plane strain (ε_zz = 0: the clamped ends
    hold the tube's length), u_r(a) = p a (1 + ν)/E ((1 − 2ν) a²/(b² − a²) + b²/(b² − a²)),
    within 2 % (measured +0.44 % on 0.5 mm cells: the clamped ends' bending zones reach the
    middle weakly at L = 5 cm). The free-ended Lamé (σ_zz = 0) is 6.6 % larger and the thin
    tube's ΔP R²/(E h) 9 % smaller (h/R = 0.2): the test tells them apart."""
    out = shared_tmp / "lame"
    code = fsi_run(
        PULSE,
        out,
        [
            "mesh.size=5.0e-4",
            "mesh.local_size=5.0e-4",
            "structure.interface_load=inlet_pressure",
            "structure.time_integration={scheme: quasi_static}",
            "fluid.inlet={kind: pressure, formula: '100'}",
            "time.end=1.0e-3",
            "time.schedule=[{until: 1.0e-3, dt: 1.0e-3}]",
        ],
    )
    assert code == 0
    row = metrics_csv.read_metrics(out / "metrics.csv")[-1]
    p, a, b, E, nu = 100.0, 0.005, 0.006, 3.0e5, 0.3
    lame = p * a * (1 + nu) / E * ((1 - 2 * nu) * a * a / (b * b - a * a) + b * b / (b * b - a * a))
    assert row["ur_A"] == pytest.approx(lame, rel=2e-2), (row["ur_A"], lame)
    assert abs(row["uz_A"]) < 1e-2 * lame


@pytest.fixture(scope="module")
def pulse_runs():
    """The pulse's case on 1 mm cells: 2 steps straight; 1 step, then a restart to 2."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    straight, first, second = (path / n for n in ("straight", "first", "second"))
    codes = [
        fsi_run(PULSE, straight, [*COARSE, STEPS, "time.end=2.0e-4"]),
        fsi_run(PULSE, first, [*COARSE, STEPS, "time.end=1.0e-4"]),
    ]
    codes.append(fsi_run(PULSE, second, [*COARSE, STEPS, "time.end=2.0e-4"], restart=first))
    yield {"codes": codes, "straight": straight, "second": second}
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def test_a_coupled_axisymmetric_run_restarts_exactly(pulse_runs):
    """The restarted run's rows and final state are the uninterrupted run's: bit for bit on
    1 rank; on 2 (another partition in every run, test_restart's notes) the rows and the
    solution's arrays to 1e-9 as the plane cases, the IQN-ILS secant columns to 1e-7 (measured
    6e-9: a column is the difference of two iterates 10-12 coupling iterations deep, so the
    partitions' round-off is large relative to it; a missed piece of state is O(1))."""
    assert pulse_runs["codes"] == [0, 0, 0]
    assert_same_rows(pulse_runs["second"], pulse_runs["straight"])
    found = differences(pulse_runs["second"], pulse_runs["straight"])
    serial = MPI.COMM_WORLD.size == 1
    for key, difference in found.items():
        bound = 0.0 if serial else 1e-7 if key.startswith("coupling.iqn.") else 1e-9
        assert difference <= bound, (key, difference)
    assert len(rows(pulse_runs["straight"])) == 2


def test_serial_and_parallel_axisymmetric_runs_agree(pulse_runs, shared_tmp):
    """The same 2 steps on every rank alone and on all ranks: peaks and point A's displacement
    to 1e-7 relative (the coupling tolerance is 1e-6; the plane cases' test_run holds 1e-8 on
    the fluid peaks)."""
    comm = MPI.COMM_WORLD
    alone = shared_tmp / f"alone{comm.rank}"
    case = config.load(PULSE, [*COARSE, STEPS, "time.end=2.0e-4"])
    simulation.run(case, alone, MPI.COMM_SELF)
    world = metrics_csv.read_metrics(pulse_runs["straight"] / "metrics.csv")
    self_rows = metrics_csv.read_metrics(alone / "metrics.csv")
    assert len(world) == len(self_rows) == 2
    for a, b in zip(world, self_rows):
        for key in ("peak_velocity", "peak_pressure", "peak_displacement", "ur_A"):
            assert a[key] == pytest.approx(b[key], rel=1e-7), key


def test_the_axisymmetric_stenosis_couples_its_ring_to_the_blood(shared_tmp):
    """The study's moving Newtonian case made axisymmetric (radius 3.5 mm: the study's 7 mm
    lumen as a diameter), 4 steps of its pulse: it runs, the coupling converges, the plaque
    ring and the wall move outward under the pulse, and the flow rates are in m³/s (of the
    order of the pipe's π R² × the peak velocity / 2)."""
    out = shared_tmp / "ring"
    code = fsi_run(
        "configs/stenosis_moving_newtonian.yaml",
        out,
        [
            "geometry.axisymmetric=true",
            "geometry.plaque_sides=null",
            "geometry.height=0.0035",
            "time.end=0.001",
        ],
    )
    assert code == 0
    last = metrics_csv.read_metrics(out / "metrics.csv")[-1]
    assert last["peak_displacement"] > 0
    radius = 0.0035
    scale = math.pi * radius**2 * last["peak_velocity"]
    assert 0.05 * scale < last["inlet_flow_rate"] < scale
