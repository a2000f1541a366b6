"""``structure.prestress`` through ``fsi run`` (fsi/physics/prestress.py; docs/arterial-wall.md):
the elastic tube's wall drawn under 2 kPa, HGO, loaded by its inner pressure alone
(``interface_load: inlet_pressure``, generalized-α). Held at the prestress pressure it stays
where it is drawn; raised, it moves, and a restart continues it exactly with the reference
taken from the checkpoint; a prestress of nothing is refused. Serially and on 2 ranks."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import pytest
from test_restart import assert_same_rows, assert_same_state, fsi_run, stored

from fsi import cli
from fsi.output import metrics_csv

PULSE = "configs/axisymmetric/tube_pulse.yaml"
# A fibre-reinforced wall stiff enough for a vessel of R 5 mm, h 1 mm at 2 kPa (c = 30 kPa,
# k1 = 100 kPa): its stress-free reference is 0.11 mm inside the drawn tube.
HGO_WALL = (
    "structure.wall={law: hgo, density: 1200, young_modulus: 9.0e+4, poisson_ratio: 0.4999, "
    "fibres: {k1: 1.0e+5, k2: 1.0, angle: 29}}"
)
CASE = [
    "mesh.size=1.0e-3",
    "mesh.local_size=1.0e-3",
    "structure.interface_load=inlet_pressure",
    HGO_WALL,
    "structure.prestress={pressure: 2000, load_steps: 10}",
    "time.schedule=[{until: 2.0e-4, dt: 1.0e-4}]",
    "output.checkpoint_every=1",
    "output.fields_every=100000",
]
HELD = "fluid.inlet={kind: pressure, formula: '2000'}"
RAISED = "fluid.inlet={kind: pressure, formula: '2000 + 1.0e7 * t'}"  # 4 kPa at 0.2 ms


@pytest.fixture(scope="module")
def runs():
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    out = {name: path / name for name in ("held", "straight", "first", "second")}
    codes = [
        fsi_run(PULSE, out["held"], [*CASE, HELD, "time.end=2.0e-4"]),
        fsi_run(PULSE, out["straight"], [*CASE, RAISED, "time.end=2.0e-4"]),
        fsi_run(PULSE, out["first"], [*CASE, RAISED, "time.end=1.0e-4"]),
    ]
    codes.append(
        fsi_run(PULSE, out["second"], [*CASE, RAISED, "time.end=2.0e-4"], restart=out["first"])
    )
    yield {"codes": codes, **out}
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def test_held_at_the_prestress_pressure_the_wall_stays_where_it_is_drawn(runs):
    """max |η| ≤ 1e-4 of the wall thickness at every step (measured 8e-17 m: round-off)."""
    assert runs["codes"] == [0, 0, 0, 0]
    for row in metrics_csv.read_metrics(runs["held"] / "metrics.csv"):
        assert row["peak_displacement"] <= 1e-4 * 1e-3, row
    raised = metrics_csv.read_metrics(runs["straight"] / "metrics.csv")[-1]
    assert raised["peak_displacement"] > 1e-6  # 2 kPa more moves it (measured 1.5e-5 m)


def test_a_prestressed_run_restarts_exactly_with_its_reference_from_the_checkpoint(runs):
    """Rows and state as the uninterrupted run's (bit for bit on 1 rank, 1e-9 on 2); the
    checkpoint holds the stress-free reference's offset U₀."""
    assert runs["codes"] == [0, 0, 0, 0]
    assert_same_rows(runs["second"], runs["straight"])
    assert_same_state(runs["second"], runs["straight"])
    if MPI.COMM_WORLD.rank == 0:
        assert "solid.reference_offset" in stored(runs["first"])


def test_a_prestress_without_a_structure_is_refused(tmp_path, capsys):
    """``structure.prestress`` with ``structure.mode: rigid``: exit 2 naming the key."""
    out = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0)) / "rigid"
    code = cli.main(
        [
            "run", PULSE, "--out", str(out),
            "--set", "structure.mode=rigid",
            "--set", "structure.prestress={pressure: 2000}",
        ]
    )  # fmt: skip
    assert code == 2
    if MPI.COMM_WORLD.rank == 0:  # rank 0 says it
        assert "structure.prestress" in capsys.readouterr().err
    assert not out.exists()


def test_a_prestress_that_cannot_be_found_fails_before_the_first_step(tmp_path, capsys):
    """A soft wall (c = 3 kPa) at 20 kPa in 2 load steps: the inverse solve fails; exit 3 and
    a message that names the key and says it failed before the first step."""
    out = Path(MPI.COMM_WORLD.bcast(str(tmp_path), root=0)) / "soft"
    soft = (
        "structure.wall={law: hgo, density: 1200, young_modulus: 9.0e+3, poisson_ratio: "
        "0.4999, fibres: {k1: 1.0e+3, k2: 1.0, angle: 29}}"
    )
    settings = [*CASE[:3], soft, "structure.prestress={pressure: 20000, load_steps: 2}"]
    code = cli.main(["run", PULSE, "--out", str(out), *sum((["--set", s] for s in settings), [])])
    assert code == 3
    if MPI.COMM_WORLD.rank == 0:
        err = capsys.readouterr().err
        assert "structure.prestress: no stress-free reference found" in err
        assert "before the first step" in err
