"""The field files match the metrics: solid.xdmf holds each cell's extreme of the computed
stresses and the cell's region, so the per-region maxima of metrics.csv are the maxima of the
written fields restricted to each region (issue #10)."""

import xml.etree.ElementTree as ET
from pathlib import Path

from mpi4py import MPI

import h5py
import numpy as np
import pytest

from fsi import cli
from fsi.geometry.tags import Region
from fsi.output import metrics_csv

CASE = "configs/stenosis_moving_newtonian.yaml"


@pytest.fixture(scope="module")
def run():
    comm = MPI.COMM_WORLD
    import tempfile

    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-fields-") if comm.rank == 0 else None))
    out = path / "run"
    assert (
        cli.main(
            [
                "run",
                CASE,
                "--out",
                str(out),
                "--set",
                "time.end=0.002",
                "--set",
                "time.schedule=[{until: 0.002, dt: 0.001}]",
            ]
        )
        == 0
    )
    yield out
    comm.barrier()
    if comm.rank == 0:
        import shutil

        shutil.rmtree(path, ignore_errors=True)


def cell_data(xdmf: Path, t: float) -> dict[str, np.ndarray]:
    """The cell fields of ``xdmf`` at time ``t``, read from its HDF5 file (dolfinx writes a
    time series per function, a grid per time holding that function)."""
    data = {}
    for grid in ET.parse(xdmf).iter("Grid"):
        time = grid.find("Time")
        if time is None or abs(float(time.get("Value")) - t) > 1e-12:
            continue
        for attribute in grid.findall("Attribute"):
            if attribute.get("Center") == "Cell":
                file, dataset = attribute.find("DataItem").text.strip().split(":")
                with h5py.File(xdmf.parent / file, "r") as f:
                    data[attribute.get("Name")] = np.asarray(f[dataset]).ravel()
    assert data, f"{xdmf}: no cell fields at t = {t}"
    return data


def test_the_per_region_maxima_are_the_maxima_of_the_written_fields(run):
    rows = metrics_csv.read_metrics(run / "metrics.csv")
    assert len(rows) == 2
    for row in rows:
        cells = cell_data(run / "solid.xdmf", row["t"])
        region = cells["region"].round().astype(int)
        assert set(region) == {int(Region.WALL), int(Region.CAP), int(Region.LIPID)}
        for r in (Region.WALL, Region.CAP, Region.LIPID):
            inside = region == int(r)
            written = {
                "max_sss": np.abs(cells["sss"][inside]).max(),
                "max_von_mises": cells["von_mises"][inside].max(),
                "max_principal": cells["max_principal"][inside].max(),
            }
            for name, value in written.items():
                column = f"{name}_{r.label}"
                assert value == pytest.approx(row[column], rel=1e-9), (column, row["t"])
        # The whole structure: the largest of the regions.
        for name in ("max_sss", "max_von_mises", "max_principal"):
            assert row[name] == max(
                row[f"{name}_{r.label}"] for r in (Region.WALL, Region.CAP, Region.LIPID)
            )
        assert row["max_sss_cap"] > 0 and row["max_principal_cap"] > 0
