"""``fsi plot``: field pictures from a run's XDMF/HDF5 files, checked against the files read
directly with h5py."""

import math
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import h5py
import numpy as np
import pytest

from fsi import cli
from fsi.output import field_files, plot

PNG = b"\x89PNG\r\n\x1a\n"
CASE = "configs/stenosis_moving_newtonian.yaml"


def steps_to(t_end: float) -> list[str]:
    return ["--set", f"time.end={t_end}", "--set", f"time.schedule=[{{until: {t_end}, dt: 0.001}}]"]


@pytest.fixture(scope="module")
def run_dir():
    """A coupled moving-wall run of 2 steps (t = 0.001, 0.002), restarted from its checkpoint
    at step 2 for one more step: ``fields.xdmf``/``solid.xdmf`` hold t = 0, 0.001, 0.002 and
    the restart segments ``*.restart2.xdmf`` hold t = 0.002 (again) and 0.003."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    out = path / "moving"
    assert cli.main(["run", CASE, "--out", str(out), *steps_to(0.002)]) == 0
    assert cli.main(["run", CASE, "--out", str(out), "--restart", str(out), *steps_to(0.003)]) == 0
    yield out
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def stored(h5: Path, name: str, t: float) -> np.ndarray:
    """Field ``name`` at time ``t`` read directly from an HDF5 file dolfinx wrote (datasets
    named by the time with '_' for '.')."""
    with h5py.File(h5, "r") as f:
        group = f[f"Function/{name}"]
        keys = [k for k in group if abs(float(k.replace("_", ".")) - t) < 1e-12]
        assert len(keys) == 1, (h5, name, t, list(group))
        return group[keys[0]][...]


def mesh(h5: Path) -> tuple[np.ndarray, np.ndarray]:
    with h5py.File(h5, "r") as f:
        return f["Mesh/mesh/geometry"][...], f["Mesh/mesh/topology"][...]


def draw(run_dir: Path, name: str, *options: str) -> Path:
    """``fsi plot`` on every rank; the picture's path (written by rank 0)."""
    out = run_dir.parent / f"{name}.png"
    assert cli.main(["plot", str(run_dir), "--out", str(out), *options]) == 0
    return out


def is_png(path: Path) -> bool:
    return path.read_bytes()[:8] == PNG


def test_a_fluid_field_is_drawn_with_the_values_of_the_file(run_dir):
    out = draw(run_dir, "pressure", "--field", "pressure", "--time", "0.001")
    snapshot = field_files.read_field(run_dir, "pressure", 0.001)
    pressure = stored(run_dir / "fields.h5", "pressure", 0.001)
    assert snapshot.file.name == "fields.xdmf" and snapshot.time == pytest.approx(0.001)
    assert snapshot.values.shape == (len(pressure),)
    assert snapshot.values.max() == pressure.max() and snapshot.values.min() == pressure.min()
    assert np.any(pressure != 0.0)
    # The fluid of a coupled run is drawn on its current mesh: reference + mesh displacement.
    reference, triangles = mesh(run_dir / "fields.h5")
    d = stored(run_dir / "fields.h5", "mesh_displacement", 0.001)[:, :2]
    assert np.abs(d).max() > 0.0
    assert snapshot.warp == 1.0
    np.testing.assert_array_equal(snapshot.coordinates, reference + d)
    np.testing.assert_array_equal(snapshot.triangles, triangles)
    if MPI.COMM_WORLD.rank == 0:
        assert is_png(out)


def test_a_structure_field_is_drawn_warped(run_dir):
    out = draw(run_dir, "sss-warped", "--field", "sss", "--time", "0.003", "--warp", "100")
    snapshot = field_files.read_field(run_dir, "sss", 0.003, warp=100.0)
    h5 = run_dir / "solid.restart2.h5"  # t = 0.003 is in the restarted segment only
    assert snapshot.file.name == "solid.restart2.xdmf"
    reference, _ = mesh(h5)
    eta = stored(h5, "eta", 0.003)[:, :2]
    assert np.abs(eta).max() > 1e-6
    np.testing.assert_allclose(snapshot.coordinates, reference + 100.0 * eta, rtol=0, atol=1e-15)
    sss = stored(h5, "sss", 0.003).reshape(-1)
    assert snapshot.center == "cell" and snapshot.values.max() == sss.max()
    # The structure's default is its reference shape.
    np.testing.assert_array_equal(
        field_files.read_field(run_dir, "sss", 0.003).coordinates, reference
    )
    if MPI.COMM_WORLD.rank == 0:
        assert is_png(out)
        # The function the report calls: the same picture from Python.
        api = run_dir.parent / "api.png"
        assert plot.field_snapshot(run_dir, "sss", 0.003, api, warp=100.0) == api
        assert is_png(api)


def test_a_region_keeps_only_its_cells(run_dir):
    out = draw(run_dir, "sss-cap", "--field", "sss", "--time", "0.002", "--region", "cap")
    snapshot = field_files.read_field(run_dir, "sss", 0.002, region="cap")
    h5 = run_dir / "solid.restart2.h5"  # t = 0.002 is in both segments: the later one wins
    assert snapshot.file.name == "solid.restart2.xdmf"
    tags = stored(h5, "region", 0.002).reshape(-1)
    _, triangles = mesh(h5)
    assert set(np.unique(tags)) == {2.0, 3.0, 4.0}
    assert np.all(tags[snapshot.cells] == 3.0)
    assert len(snapshot.cells) == np.count_nonzero(tags == 3.0)
    np.testing.assert_array_equal(snapshot.triangles, triangles[tags == 3.0])
    np.testing.assert_array_equal(
        snapshot.values, stored(h5, "sss", 0.002).reshape(-1)[tags == 3.0]
    )
    if MPI.COMM_WORLD.rank == 0:
        assert is_png(out)


def test_streamlines_are_drawn_over_a_fluid_field(run_dir):
    plain = draw(run_dir, "velocity", "--field", "velocity", "--time", "0.003")
    lines = draw(
        run_dir, "velocity-streamlines", "--field", "velocity", "--time", "0.003", "--streamlines"
    )
    snapshot = field_files.read_field(run_dir, "velocity", 0.003)
    flow = plot.streamline_field(snapshot)
    u = stored(run_dir / "fields.restart2.h5", "velocity", 0.003)
    assert u.shape[1] == 3 and not np.any(u[:, 2])  # 2D vectors stored with 3 components
    np.testing.assert_array_equal(flow.values, u[:, :2])
    np.testing.assert_array_equal(flow.coordinates, snapshot.coordinates)
    if MPI.COMM_WORLD.rank == 0:
        assert is_png(lines) and is_png(plain)
        assert lines.read_bytes() != plain.read_bytes()


def test_the_nearest_stored_time_is_taken_and_said(run_dir, capsys):
    assert field_files.read_field(run_dir, "pressure", 0.0014).time == pytest.approx(0.001)
    assert not field_files.read_field(run_dir, "pressure", 0.0014).time_differs
    beyond = field_files.read_field(run_dir, "pressure", 0.0038)  # within a step of the last time
    assert beyond.time == pytest.approx(0.003) and beyond.time_differs
    assert "nearest stored to 0.0038 s" in plot.title(beyond)
    capsys.readouterr()
    draw(run_dir, "beyond", "--field", "pressure", "--time", "0.0038")
    if MPI.COMM_WORLD.rank == 0:
        assert "pressure is stored at t = 0.003 s, the nearest to --time 0.0038" in (
            capsys.readouterr().out
        )


@pytest.mark.parametrize(
    "times, t, expected",
    [
        ([0.0, 0.001, 0.002], 0.0012, (1, 0.001)),
        ([0.0, 0.001, 0.003], 0.0025, (2, 0.002)),
        ([0.0, 0.001, 0.002], -0.001, (0, 0.001)),
        ([0.0, 0.001, 0.002], 0.003, (2, 0.001)),
        ([0.5], 0.5, (0, 0.0)),
    ],
)
def test_pick_time(times, t, expected):
    i, step = field_files.pick_time(times, t, "f.xdmf")
    assert (i, step) == (expected[0], pytest.approx(expected[1]))


@pytest.mark.parametrize(
    "times, t", [([0.0, 0.001], 0.0021), ([0.0, 0.001], -0.0011), ([0.5], 0.5001)]
)
def test_pick_time_refuses_a_time_outside_the_stored_range(times, t):
    with pytest.raises(plot.PlotError, match=r"--time .*outside the times stored in f\.xdmf"):
        field_files.pick_time(times, t, "f.xdmf")


BAD = [
    (
        ["--field", "nope", "--time", "0.001"],
        "--field nope: {run} has no such field (fields.xdmf has mesh_displacement, pressure, "
        "shear_rate, velocity, viscosity, wall_shear_stress; solid.xdmf has eta, max_principal, "
        "region, sss, von_mises)",
    ),
    (
        ["--field", "sss", "--time", "0.001", "--region", "fluid"],
        "--region fluid: 'sss' is a structure field (solid.xdmf): use --region wall, cap, lipid "
        "or flag",
    ),
    (
        ["--field", "velocity", "--time", "0.001", "--region", "cap"],
        "--region cap: 'velocity' is a fluid field (fields.xdmf): use --region fluid",
    ),
    (
        ["--field", "velocity", "--time", "0.0041"],
        "--time 0.0041: outside the times stored in {run}/fields.xdmf, fields.restart2.xdmf "
        "(0 to 0.003 s)",
    ),
    (
        ["--field", "velocity", "--time", "-0.0011"],
        "--time -0.0011: outside the times stored in {run}/fields.xdmf, fields.restart2.xdmf "
        "(0 to 0.003 s)",
    ),
    (
        ["--field", "sss", "--time", "0.001", "--region", "flag"],
        "--region flag: no flag cells in {run}/solid.xdmf",
    ),
    (
        ["--field", "pressure", "--time", "0.001", "--component", "x"],
        "--component x: 'pressure' is a scalar field",
    ),
    (
        ["--field", "sss", "--time", "0.001", "--streamlines"],
        "--streamlines: draws the fluid velocity over a fluid field, but 'sss' is a structure "
        "field (solid.xdmf)",
    ),
    (["--field", "sss", "--time", "nan"], "--time nan: not a finite number"),
    (["--field", "sss", "--time", "0.001", "--warp", "inf"], "--warp inf: not a finite number"),
]


@pytest.mark.parametrize("options, message", BAD)
def test_bad_input_is_refused_with_one_line_and_nothing_written(run_dir, options, message, capsys):
    out = run_dir.parent / "refused" / "bad.png"
    assert cli.main(["plot", str(run_dir), *options, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    if MPI.COMM_WORLD.rank == 0:
        assert err == f"fsi: error: {message.format(run=run_dir)}\n"
    assert not out.parent.exists()


def test_a_missing_or_foreign_folder_and_a_bad_out_are_refused(run_dir, capsys):
    out = run_dir.parent / "refused" / "bad.png"
    missing = run_dir.parent / "missing"
    cases = [
        ([str(missing), "--out", str(out)], f"{missing}: no such folder"),
        (
            [str(run_dir / "checkpoint"), "--out", str(out)],
            f"{run_dir / 'checkpoint'}: no fields.xdmf or solid.xdmf (not a folder written "
            "by fsi run)",
        ),
        (
            [str(run_dir), "--out", str(out.with_suffix(".jpg"))],
            f"--out {out.with_suffix('.jpg')}: the picture's file name must end in .png, "
            ".pdf, .svg",
        ),
    ]
    for arguments, message in cases:
        assert cli.main(["plot", *arguments, "--field", "velocity", "--time", "0"]) == 2
        if MPI.COMM_WORLD.rank == 0:
            assert capsys.readouterr().err == f"fsi: error: {message}\n"
    assert not out.parent.exists()


def test_fsi_report_includes_snapshots_at_the_report_times(run_dir):
    """``fsi report --out`` draws σ₁₂ on the structure and the velocity with streamlines at
    each report time the run has reached, and lists them in report.md."""
    out = run_dir.parent / "report"
    assert cli.main(["report", str(run_dir), "--out", str(out), "--times", "0.002", "0.5"]) == 0
    if MPI.COMM_WORLD.rank == 0:
        name = run_dir.name
        for field in ("sss", "velocity"):
            assert is_png(out / f"{name}_{field}_t0.002.png")
            assert not (out / f"{name}_{field}_t0.5.png").exists()  # not reached
            assert f"{name}_{field}_t0.002.png" in (out / "report.md").read_text()


def test_a_picture_for_a_paper_is_a_pdf_or_an_svg(run_dir):
    """``fsi plot --out FILE.pdf`` or ``.svg`` writes that format (the file's own signature);
    ``fsi report --format`` writes every plot and snapshot in it and links them in report.md."""
    stem = run_dir.parent / "paper"
    for suffix, signature in ((".pdf", b"%PDF-"), (".svg", b"<svg")):
        out = stem.with_suffix(suffix)
        assert cli.main(["plot", str(run_dir), "--field", "velocity", "--time", "0.002",
                         "--out", str(out)]) == 0  # fmt: skip
        if MPI.COMM_WORLD.rank == 0:
            head = out.read_bytes()[:2000]
            assert head.startswith(signature) or signature in head, (suffix, head[:80])
    out = run_dir.parent / "report_svg"
    assert cli.main(["report", str(run_dir), "--out", str(out), "--format", "svg",
                     "--times", "0.002"]) == 0  # fmt: skip
    if MPI.COMM_WORLD.rank == 0:
        text = (out / "report.md").read_text()
        for name in ("peak_velocity", f"{run_dir.name}_velocity_t0.002"):
            assert b"<svg" in (out / f"{name}.svg").read_bytes()[:2000]
            assert f"![{name}.svg]({name}.svg)" in text
        assert not list(out.glob("*.png"))


# --------------------------------------------------------------------------------------------
# The wall indices along the walls (wall_indices.csv)


def test_tawss_along_the_walls_is_drawn_from_wall_indices_csv(run_dir, capsys):
    """``--field tawss``: the file's TAWSS against x, one line per wall and side, x increasing;
    ``fsi report`` draws TAWSS and OSI for the run."""
    import csv

    from fsi.output import wall_plot

    with (run_dir / "wall_indices.csv").open() as f:
        rows = list(csv.DictReader(f))
    index = wall_plot.read(run_dir, "tawss")
    assert index.cycle is None
    assert set(index.lines) == {f"{r['wall']}, {r['side']}" for r in rows}
    for label, (x, y) in index.lines.items():
        mine = sorted(
            (float(r["x"]), float(r["TAWSS"])) for r in rows if f"{r['wall']}, {r['side']}" == label
        )
        assert (x, y) == ([a for a, _ in mine], [b for _, b in mine])
    assert max(max(y) for _, y in index.lines.values()) > 0
    for name in ("tawss", "osi", "rrt"):
        assert is_png(draw(run_dir, f"wall_{name}", "--field", name))
    out = run_dir.parent / f"report_walls{MPI.COMM_WORLD.rank}"
    assert cli.main(["report", str(run_dir), "--out", str(out), "--times", "0.002"]) == 0
    if MPI.COMM_WORLD.rank == 0:
        for name in ("tawss", "osi"):
            assert is_png(out / f"{run_dir.name}_{name}.png")
            assert f"![{run_dir.name}_{name}.png]" in (out / "report.md").read_text()


def test_a_truncated_or_damaged_wall_indices_csv_is_refused_naming_the_line(shared_tmp, capsys):
    """A wall_indices.csv whose last row was cut short said "a value is not a number (float()
    argument must be ... not 'NoneType')": now the file, the line and the column are named,
    exit 2, nothing drawn. An empty cell (the file's way of writing a value that is not a
    number, OSI where TAWSS is 0) is drawn as a gap, not refused."""
    from fsi.output import wall_plot

    header = "cycle,wall,side,x,y,TAWSS,OSI,RRT"
    good = [f"1,interface,lower,{x},0,1.5,,2" for x in (0.001, 0.002)]
    cases = {
        "cut": ([*good, "1,interface,lower,0.003,0"], "line 4: the row ends before its TAWSS"),
        "text": ([*good, "1,interface,lower,0.003,0,abc,0,1"], "line 4: TAWSS = 'abc' is not a"),
        "beat": ([*good, "x,interface,lower,0.003,0,1,0,1"], "line 4: cycle = 'x' is not a whole"),
    }
    for name, (rows, message) in cases.items():
        run = shared_tmp / name
        if MPI.COMM_WORLD.rank == 0:
            run.mkdir()
            (run / "wall_indices.csv").write_text("\n".join([header, *rows]))
        MPI.COMM_WORLD.barrier()
        out = shared_tmp / f"{name}.png"
        capsys.readouterr()
        assert cli.main(["plot", str(run), "--field", "tawss", "--out", str(out)]) == 2
        if MPI.COMM_WORLD.rank == 0:
            err = capsys.readouterr().err
            assert err.startswith(f"fsi: error: {run / 'wall_indices.csv'}: {message}"), err
            assert err.count("\n") == 1 and not out.exists(), err
    run = shared_tmp / "gaps"
    if MPI.COMM_WORLD.rank == 0:
        run.mkdir()
        (run / "wall_indices.csv").write_text("\n".join([header, *good]) + "\n")
    MPI.COMM_WORLD.barrier()
    osi = wall_plot.read(run, "osi")
    assert all(math.isnan(v) for v in osi.lines["interface, lower"][1])


def test_the_title_of_a_partial_heartbeat_says_so(shared_tmp):
    """A run stopped in its second heartbeat (period 4 ms, metrics to 6 ms): TAWSS over that
    heartbeat was titled "heartbeat 2 (the last in the file)" as if it were whole; now
    "heartbeat 2 (partial: to t = 0.006 s of 0.008 s)". A finished beat keeps its title."""
    from fsi import config
    from fsi.output import wall_plot

    run = shared_tmp / "partial"
    if MPI.COMM_WORLD.rank == 0:
        run.mkdir()
        case = config.load(
            "configs/channel_poiseuille.yaml",
            [
                "fluid.inlet={kind: pressure_table, table: [[0, 0], [0.004, 1]], period: 0.004}",
                "time.end=0.008",
                "time.schedule=[{until: 0.008, dt: 0.001}]",
            ],
        )
        config.dump(case, run / "config.yaml")
        rows = "".join(f"{k},{k * 0.001!r},0.001\n" for k in range(1, 7))
        (run / "metrics.csv").write_text("step,t,dt\n" + rows)
        lines = ["cycle,wall,side,x,y,TAWSS,OSI,RRT"]
        lines += [f"{c},interface,lower,{x},0,1,0.1,1" for c in (1, 2) for x in (0.001, 0.002)]
        (run / "wall_indices.csv").write_text("\n".join(lines) + "\n")
    MPI.COMM_WORLD.barrier()
    last = wall_plot.title(wall_plot.read(run, "tawss"))
    assert last.endswith("over heartbeat 2 (partial: to t = 0.006 s of 0.008 s)"), last
    assert wall_plot.title(wall_plot.read(run, "tawss", cycle=1)).endswith("over heartbeat 1")


def test_a_heartbeat_of_the_wall_indices_is_chosen_with_cycle(shared_tmp, capsys):
    """With a ``cycle`` column the last heartbeat in the file is drawn unless ``--cycle K``
    names another; a heartbeat the file lacks, ``--cycle`` without heartbeats, and options that
    belong to fields are refused with exit 2 and one line naming them."""
    from fsi.output import wall_plot

    run = shared_tmp / "beats"
    if MPI.COMM_WORLD.rank == 0:
        run.mkdir()
        lines = ["cycle,wall,side,x,y,TAWSS,OSI,RRT"]
        for cycle in (1, 2):
            for x in (0.002, 0.001, 0.003):
                lines.append(f"{cycle},interface,lower,{x},0,{cycle * x * 1e3},0.1,{1 / x}")
        (run / "wall_indices.csv").write_text("\n".join(lines) + "\n")
    MPI.COMM_WORLD.barrier()
    last = wall_plot.read(run, "tawss")
    assert (last.cycle, last.cycles) == (2, 2)
    assert last.lines["interface, lower"] == ([0.001, 0.002, 0.003], [2.0, 4.0, 6.0])
    first = wall_plot.read(run, "tawss", cycle=1)
    assert first.lines["interface, lower"][1] == [1.0, 2.0, 3.0]
    assert "over heartbeat 1" in wall_plot.title(first)
    out = shared_tmp / "beat.svg"
    assert cli.main(["plot", str(run), "--field", "osi", "--cycle", "1", "--out", str(out)]) == 0
    refused = [
        (["--field", "tawss", "--cycle", "3"], f"--cycle 3: {run / 'wall_indices.csv'} holds "
         "heartbeats 1 to 2"),
        (["--field", "tawss", "--time", "0.1"], "--time: not for --field tawss, an average along "
         "the walls (over the run, or over heartbeat --cycle K)"),
        (["--field", "velocity"], "--time: required for --field velocity"),
        (["--field", "velocity", "--time", "0", "--cycle", "1"], "--cycle: only for the wall "
         "indices (tawss, osi, rrt), not --field velocity"),
    ]  # fmt: skip
    for options, message in refused:
        capsys.readouterr()
        bad = shared_tmp / "refused.png"
        assert cli.main(["plot", str(run), *options, "--out", str(bad)]) == 2
        if MPI.COMM_WORLD.rank == 0:
            assert capsys.readouterr().err == f"fsi: error: {message}\n"
            assert not bad.exists()
    if MPI.COMM_WORLD.rank == 0:
        assert b"<svg" in out.read_bytes()[:2000]
        (run / "wall_indices.csv").write_text(
            "wall,side,x,y,TAWSS,OSI,RRT\ninterface,lower,0,0,1,0,1\n"
        )
    MPI.COMM_WORLD.barrier()
    with pytest.raises(plot.PlotError, match="--cycle 1: .* is over the whole run"):
        wall_plot.read(run, "tawss", cycle=1)
    MPI.COMM_WORLD.barrier()


def test_region_tags_get_one_colour_each_and_other_fields_a_continuous_map():
    cmap, norm = plot._colours(np.array([3.0, 1.0, 2.0, 3.0]), "tag")
    assert cmap.N == 3 and [int(norm(tag)) for tag in (1, 2, 3)] == [0, 1, 2]
    assert len({cmap(k) for k in range(3)}) == 3  # distinct colours
    cmap, norm = plot._colours(np.array([-1.0, 3.0]), "stress")
    assert (cmap, norm.vmin, norm.vmax) == ("RdBu_r", -3.0, 3.0)  # signed: zero in the middle
    cmap, norm = plot._colours(np.array([2.0, 2.0]), "velocity")
    assert (cmap, norm.vmin, norm.vmax) == ("viridis", 1.0, 3.0)  # never an empty range


def test_a_colour_limit_caps_the_range_and_the_bar_says_so(run_dir, monkeypatch):
    """A singular peak need not wash out the rest: ±limit for signed values, the top for
    others (a limit beyond the values changes nothing); the bar gets an arrow at a cut end."""
    _, norm = plot._colours(np.array([-1.0, 30.0]), "stress", limit=2.0)
    assert (norm.vmin, norm.vmax) == (-2.0, 2.0)
    _, norm = plot._colours(np.array([-1.0, 3.0]), "stress", limit=10.0)
    assert (norm.vmin, norm.vmax) == (-3.0, 3.0)
    _, norm = plot._colours(np.array([0.5, 30.0]), "velocity", limit=2.0)
    assert (norm.vmin, norm.vmax) == (0.5, 2.0)
    if MPI.COMM_WORLD.rank != 0:
        return
    import matplotlib.figure

    extends = []
    real = matplotlib.figure.Figure.colorbar
    monkeypatch.setattr(
        matplotlib.figure.Figure,
        "colorbar",
        lambda self, *a, **k: extends.append(k["extend"]) or real(self, *a, **k),
    )
    sss = field_files.read_field(run_dir, "sss", 0.003, region="cap")
    half = 0.5 * float(np.abs(sss.values).max())  # Pa; both signs reach beyond it
    out = run_dir.parent / "capped.png"
    mark = [(0.0, 0.0, "clamped corner")]
    assert plot.field_snapshot(run_dir, "sss", 0.003, out, limit=half, marks=mark) == out
    plot.field_snapshot(run_dir, "sss", 0.003, run_dir.parent / "full.png")
    assert is_png(out) and extends[0] in ("both", "max", "min") and extends[1] == "neither"


def test_an_axisymmetric_run_is_drawn_in_z_and_r(run_dir, shared_tmp):
    """The axes are the meridian plane's z and r for an axisymmetric run (its config.yaml),
    x and y for a plane one, and for a folder without a readable configuration."""
    assert plot.axis_labels(run_dir) == ("x (mm)", "y (mm)")
    comm = MPI.COMM_WORLD
    if comm.rank == 0:
        for name, text in {
            "tube": "geometry: {kind: tube}\nstructure: {mode: rigid}\n",
            "ring": "geometry: {axisymmetric: true}\n",
            "broken": "geometry: [",
        }.items():
            (shared_tmp / name).mkdir()
            (shared_tmp / name / "config.yaml").write_text(text)
    comm.barrier()
    assert plot.axis_labels(shared_tmp / "tube") == ("z (mm)", "r (mm)")
    assert plot.axis_labels(shared_tmp / "ring") == ("z (mm)", "r (mm)")
    assert plot.axis_labels(shared_tmp / "broken") == ("x (mm)", "y (mm)")
