"""Turek–Hron FSI through ``fsi run`` (docs/turek-hron.md): the elastic flag
behind the cylinder, coupled partitioned (Dirichlet–Neumann, Aitken) on the coarse mesh."""

from mpi4py import MPI

import pytest

from fsi import cli, config
from fsi.output import metrics_csv
from fsi.run import simulation

FSI1 = "configs/turek_hron_fsi1.yaml"

# Featflow's reference (u_x(A), u_y(A) in m; drag, lift in N/m).
FSI1_REFERENCE = {"ux_A": 0.0227e-3, "uy_A": 0.8209e-3, "drag": 14.295, "lift": 0.7638}


def test_fsi1_steady_state_within_one_percent(shared_tmp):
    """The shipped FSI1 case is one steady coupled solve (steady fluid, quasi-static flag) on the
    coarse mesh (5,600 triangles, P2/P1 fluid, P2 flag), SUPG on. Measured: u_x(A) −0.09 %,
    u_y(A) −0.66 %, drag −0.07 %, lift +0.10 % (without SUPG −0.10, −0.65, −0.08, +0.11 %;
    Featflow's level 2+0 has u_y −0.19 %, drag −0.15 %); the issue asks for 1 %."""
    out = shared_tmp / "fsi1"
    assert cli.main(["run", FSI1, "--out", str(out)]) == 0
    (row,) = metrics_csv.read_metrics(out / "metrics.csv")
    for key, reference in FSI1_REFERENCE.items():
        assert row[key] == pytest.approx(reference, rel=0.01), key
    assert row["coupling_residual"] <= config.load(FSI1).coupling.tolerance


def test_fsi1_serial_and_parallel_agree(shared_tmp):
    """Same answer on every rank count: compare COMM_WORLD with COMM_SELF to the coupling
    tolerance (1e-6 relative on the interface displacement; the forces follow it)."""
    comm = MPI.COMM_WORLD
    case = config.load(FSI1)
    simulation.run(case, shared_tmp / "world", comm)
    simulation.run(case, shared_tmp / f"self{comm.rank}", MPI.COMM_SELF)
    (world,) = metrics_csv.read_metrics(shared_tmp / "world" / "metrics.csv")
    (alone,) = metrics_csv.read_metrics(shared_tmp / f"self{comm.rank}" / "metrics.csv")
    for key in FSI1_REFERENCE:
        assert world[key] == pytest.approx(alone[key], rel=1e-5), key
