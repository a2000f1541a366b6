"""Output files: metrics table (restart keeps earlier rows) and XDMF field series."""

from mpi4py import MPI

import dolfinx.fem
import dolfinx.mesh
import numpy as np

from fsi import compat
from fsi.output import io, metrics_csv


def test_metrics_table_flushes_rows_and_restarts(shared_tmp):
    comm = MPI.COMM_WORLD
    path = shared_tmp / "metrics.csv"
    table = metrics_csv.MetricsTable(comm, path, ["step", "t", "peak_velocity"])
    for k in range(1, 4):
        table.write({"step": k, "t": 0.1 * k, "peak_velocity": 1.5 * k})
        comm.barrier()
        assert len(metrics_csv.read_metrics(path)) == k  # on disk at once, before close
        comm.barrier()  # every rank has read before rank 0 writes the next row
    table.close()
    comm.barrier()
    table = metrics_csv.MetricsTable(comm, path, ["step", "t", "peak_velocity"], keep_until_step=2)
    table.write({"step": 3, "t": 0.3, "peak_velocity": -1.0})
    table.close()
    comm.barrier()
    rows = metrics_csv.read_metrics(path)
    assert [r["step"] for r in rows] == [1, 2, 3]
    assert rows[1]["peak_velocity"] == 3.0 and rows[2]["peak_velocity"] == -1.0


def test_a_negative_zero_is_written_as_zero(shared_tmp):
    """A flow rate of no flow is −∫ 0 = −0.0, which metrics.csv wrote as "-0": now "0"."""
    comm = MPI.COMM_WORLD
    path = shared_tmp / "zero.csv"
    table = metrics_csv.MetricsTable(comm, path, ["step", "t", "inlet_flow_rate"])
    table.write({"step": 1, "t": 0.001, "inlet_flow_rate": -0.0})
    table.write({"step": 2, "t": 0.002, "inlet_flow_rate": -1.5e-300})
    table.close()
    comm.barrier()
    lines = path.read_text().splitlines()
    assert lines[1:] == ["1,0.001,0", "2,0.002,-1.5e-300"], lines


def test_field_writer_writes_p2_and_dg_fields(shared_tmp):
    comm = MPI.COMM_WORLD
    mesh = dolfinx.mesh.create_unit_square(comm, 4, 4)
    u = dolfinx.fem.Function(compat.function_space(mesh, "Lagrange", 2, (2,)))
    u.name = "velocity"
    u.interpolate(lambda x: np.vstack([x[0] ** 2, x[1]]))
    mu = dolfinx.fem.Function(compat.function_space(mesh, "DG", 0))
    mu.name = "viscosity"
    mu.x.array[:] = 3.5e-3
    writer = io.FieldWriter(comm, shared_tmp / "fields.xdmf", mesh)
    for t in (0.0, 0.1):
        writer.write(t, [u, mu])
    writer.close()
    comm.barrier()
    text = (shared_tmp / "fields.xdmf").read_text()
    assert text.count('<Attribute Name="velocity"') == 2
    assert text.count('<Attribute Name="viscosity"') == 2 and 'Center="Cell"' in text
    assert (shared_tmp / "fields.h5").stat().st_size > 0
