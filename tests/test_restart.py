"""Checkpoints and ``fsi run --restart`` (fsi/run/checkpoint.py, fsi.run.simulation.march).

A run stopped after step k and restarted from its checkpoint continues like the uninterrupted
run: rigid stenosis (BDF2 across a change of dt), coupled moving wall with Aitken and with
IQN-ILS reusing the columns of past steps (also with Robin–Neumann coupling, whose iterates
hold the interface forces), also on another number of ranks. A failed step exits
3 with the last converged step checkpointed, from which a run with a working setting finishes
like the uninterrupted one. A checkpoint that does not fit the run (mesh, structure, a damaged
file) is refused with exit status 2 before anything is written.

Tolerances. On 1 rank: none. The restarted run reads back the float64 bits of every array the
next step depends on and rebuilds the same operators from the same mesh; the direct solves
(MUMPS) repeat their arithmetic for the same matrix. So metrics rows (10 digits) and the final
checkpoints' arrays must be *equal*: any difference means a piece of state was missed (without
the IQN history step 2 takes 6 coupling iterations instead of 7 and its values change in the 2nd
digit). On 2 ranks SCOTCH partitions the mesh differently in every run (measured: 865/867 vs
866/866 vertices per rank), so two runs differ in round-off even without a restart: arrays and
metrics to 1e-9 relative (measured ≤ 4e-12), iteration counts equal. The residual norms of
converged iterates (``*_residual``) are the last Newton or coupling step's leftover of that
round-off, not a value of the solution: to 1e-2 relative or 1e-12 absolute (measured up to
1.9e-4 relative: the structure alone's 5.32e-9 N/m on dolfinx 0.9; a missed piece of state
changes them in the first digit).
"""

import csv
import json
import re
import shutil
import tempfile
from pathlib import Path

from mpi4py import MPI

import numpy as np
import pytest
from scipy.spatial import cKDTree

from fsi import cli, config
from fsi.run import checkpoint, checkpoint_checks, simulation, state_arrays

RIGID = "configs/stenosis_fixed_newtonian.yaml"
COUPLED = "configs/stenosis_moving_newtonian.yaml"
# A checkpoint after every step: the configs keep their Jacobians across steps
# (``jacobian_reuse: run``) and drop them at every periodic checkpoint, so a restart from any
# step is exact (test_a_restart_from_a_periodic_checkpoint_is_exact covers a longer period).
EVERY_STEP = "output.checkpoint_every=1"
# BDF2 with dt 1 ms then 0.5 ms: the restart after step 2 needs dt_previous and u^{n-1}.
RIGID_SET = [
    "structure.mode=rigid",
    "time.schedule=[{until: 0.002, dt: 0.001}, {until: 0.004, dt: 0.0005}]",
    EVERY_STEP,
]
COUPLED_SET = ["time.schedule=[{until: 0.002, dt: 0.001}]", EVERY_STEP]
ACCELERATIONS = {
    "aitken": ["coupling.acceleration=aitken"],
    "iqn-ils": ["coupling.acceleration=iqn-ils", "coupling.iqn_reuse=2"],
    # z = [x, f] per node: the predictor's and IQN-ILS's columns hold the forces too
    "robin-neumann": [
        "coupling.acceleration=iqn-ils",
        "coupling.iqn_reuse=2",
        "coupling.scheme=robin-neumann",
        "coupling.robin_coefficient=1e6",
    ],
}
SERIAL = MPI.COMM_WORLD.size == 1
RESIDUAL_REL = 1e-2  # residual norms of converged iterates on 2 ranks (see the top)


def fsi_run(case: str, out: Path, overrides, restart: Path | None = None) -> int:
    args = ["run", case, "--out", str(out), *sum((["--set", s] for s in overrides), [])]
    return cli.main(args + ([] if restart is None else ["--restart", str(restart)]))


def stderr(capsys) -> str:
    """What rank 0 printed (only rank 0 prints), on every rank: asserts stay collective."""
    return MPI.COMM_WORLD.bcast(capsys.readouterr().err if MPI.COMM_WORLD.rank == 0 else None)


def rows(run: Path) -> list[dict]:
    """metrics.csv as written (10 significant digits), without the wall time."""
    with (run / "metrics.csv").open(newline="") as f:
        return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in csv.DictReader(f)]


def assert_same_rows(a: Path, b: Path, rel: float = 1e-9, absolute: float = 1e-12) -> None:
    """Equal on 1 rank; on more, to ``rel`` relative or ``absolute``, residual norms to
    ``RESIDUAL_REL`` (see the top)."""
    ra, rb = rows(a), rows(b)
    assert [r["step"] for r in ra] == [r["step"] for r in rb]
    if SERIAL:
        assert ra == rb
        return
    for x, y in zip(ra, rb):
        for key in x:
            if key.endswith("iterations") or x[key] == "":
                assert x[key] == y[key], key
            else:
                loose = max(rel, RESIDUAL_REL) if key.endswith("_residual") else rel
                assert float(x[key]) == pytest.approx(float(y[key]), rel=loose, abs=absolute), key


def stored(run: Path) -> dict[str, tuple]:
    """Every rank file of ``run``'s checkpoint: per array (keys of its rows or None, values)."""
    folder = run / "checkpoint"
    meta = json.loads((folder / "checkpoint.json").read_text())
    files = []
    for name in meta["files"]:
        with np.load(folder / name) as data:
            files.append({k: data[k] for k in data.files})
    return {
        key: (None, files[0][key])
        if layout is None
        else (
            np.concatenate([f[f"keys.{layout}"] for f in files]),
            np.concatenate([f[key] for f in files]),
        )
        for key, layout in meta["layouts"].items()
    }


def differences(a: Path, b: Path) -> dict[str, float]:
    """max |a − b| / max |a| per array of two runs' checkpoints (rows paired by their keys);
    inf for arrays that are missing or of another shape. Computed on rank 0."""
    result = None
    if MPI.COMM_WORLD.rank == 0:
        sa, sb = stored(a), stored(b)
        result = {k: np.inf for k in set(sa) ^ set(sb)}
        for key in set(sa) & set(sb):
            (keys_a, x), (keys_b, y) = sa[key], sb[key]
            if keys_a is not None and len(keys_a) == len(keys_b) and len(keys_a):
                distance, index = cKDTree(keys_b).query(keys_a)
                y = y[index] if distance.max() < 1e-12 else y[:0]
            if x.shape != y.shape:
                result[key] = np.inf
            elif x.dtype == bool or not x.size:
                result[key] = 0.0 if np.array_equal(x, y) else np.inf
            else:
                scale = np.abs(x).max() or 1.0
                result[key] = float(np.abs(x.astype(float) - y).max() / scale)
    return MPI.COMM_WORLD.bcast(result, root=0)


def assert_same_state(a: Path, b: Path, rel: float = 1e-9) -> None:
    bound = 0.0 if SERIAL else rel
    different = {k: d for k, d in differences(a, b).items() if d > bound}
    assert not different, different


def step_of(run: Path) -> int:
    return json.loads((run / "checkpoint" / "checkpoint.json").read_text())["step"]


def summary(run: Path) -> dict:
    return json.loads((run / "summary.json").read_text())


# --------------------------------------------------------------------------------------------
# Rigid structure: the fluid alone


@pytest.fixture(scope="module")
def rigid():
    """6 steps straight; 2 steps, then a restart in the same folder up to step 6."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    straight, split = path / "straight", path / "split"
    codes = [
        fsi_run(RIGID, straight, [*RIGID_SET, "time.end=0.004"]),
        fsi_run(RIGID, split, [*RIGID_SET, "time.end=0.002"]),
    ]
    before = (split / "fields.xdmf").read_text()
    codes.append(fsi_run(RIGID, split, [*RIGID_SET, "time.end=0.004"], restart=split))
    yield {"codes": codes, "straight": straight, "split": split, "fields_before": before}
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


def test_rigid_restart_continues_like_the_uninterrupted_run(rigid):
    assert rigid["codes"] == [0, 0, 0]
    straight, split = rigid["straight"], rigid["split"]
    assert [r["step"] for r in rows(split)] == ["1", "2", "3", "4", "5", "6"]
    assert_same_rows(split, straight)
    assert step_of(split) == step_of(straight) == 6
    assert_same_state(split, straight)
    s, r = summary(straight), summary(split)
    for key in ("steps", "newton_iterations", "end_time_s"):
        assert r[key] == s[key], key
    assert r["restarted_from"]["step"] == 2


def test_restart_writes_a_new_field_file_and_keeps_the_old_one(rigid):
    split = rigid["split"]
    # fields.xdmf (t = 0 … 2 ms) is untouched; the restart's fields (t = 2 … 4 ms) are new.
    assert (split / "fields.xdmf").read_text() == rigid["fields_before"]
    text = (split / "fields.restart2.xdmf").read_text()
    times = [float(t) for t in re.findall(r'Time Value="([^"]+)"', text)]
    assert times[0] == 0.002 and times[-1] == pytest.approx(0.004) and len(set(times)) == 5


def test_checkpoints_every_n_steps_and_at_the_end(shared_tmp, monkeypatch):
    written = []
    original = checkpoint.write

    def spy(out, comm, state, layouts, meta):
        written.append(meta["step"])
        return original(out, comm, state, layouts, meta)

    monkeypatch.setattr(checkpoint, "write", spy)
    out = shared_tmp / "every"
    assert fsi_run(RIGID, out, [*RIGID_SET, "time.end=0.0025", "output.checkpoint_every=2"]) == 0
    assert written == [2, 3]
    assert step_of(out) == 3
    assert summary(out)["checkpoint"] == str(out / "checkpoint")


def test_a_restart_from_a_periodic_checkpoint_is_exact(shared_tmp):
    """With ``jacobian_reuse: run`` (the configs') the solvers keep their Jacobians across steps
    and drop them at every periodic checkpoint (here every 3 steps): restarted from step 3's
    checkpoint the run continues bit for bit like the uninterrupted one. From step 2's (the end
    of a shorter run, not a periodic checkpoint) the restarted run starts with a fresh Jacobian
    where the uninterrupted one kept step 2's: the same answer to the Newton tolerance, not to
    the bit, which shows the kept Jacobian matters."""
    every3 = [*RIGID_SET, "output.checkpoint_every=3", "fluid.solver.jacobian_reuse=run"]
    straight = shared_tmp / "straight"
    assert fsi_run(RIGID, straight, [*every3, "time.end=0.004"]) == 0
    for name, end in (("periodic", 0.0025), ("last", 0.002)):
        out = shared_tmp / name
        assert fsi_run(RIGID, out, [*every3, f"time.end={end}"]) == 0
        assert fsi_run(RIGID, out, [*every3, "time.end=0.004"], restart=out) == 0
    assert_same_rows(shared_tmp / "periodic", straight)
    assert_same_state(shared_tmp / "periodic", straight)
    # Measured: the velocity-pressure vector 1.6e-7 of its largest value, at most 7e-6 in the
    # wall indices' sums (their small entries move most).
    differences_last = differences(shared_tmp / "last", straight)
    assert 0 < max(differences_last.values()) < 1e-4, differences_last
    assert differences_last["fluid.U"] < 1e-6, differences_last


def test_a_checkpoint_restarts_on_another_number_of_ranks(rigid, shared_tmp):
    """The checkpoint of step 2 (written by every rank of the world) continued by each rank
    alone; compared with the uninterrupted run on all ranks."""
    comm = MPI.COMM_WORLD
    case = config.load(RIGID, [*RIGID_SET, "time.end=0.004"])
    source = shared_tmp / "source"
    assert fsi_run(RIGID, source, [*RIGID_SET, "time.end=0.002"]) == 0
    alone = shared_tmp / f"alone{comm.rank}"
    found = checkpoint.read(source, case, MPI.COMM_SELF)
    assert found.meta["ranks"] == comm.size and found.step == 2
    simulation.run(case, alone, MPI.COMM_SELF, found)
    reference = rows(rigid["straight"])
    mine = rows(alone)
    problems = [] if [r["step"] for r in mine] == [r["step"] for r in reference] else ["steps"]
    for x, y in zip(mine, reference):  # another partition: round-off only (see the top)
        problems += [
            (x["step"], key, x[key], y[key])
            for key in ("peak_velocity", "peak_pressure", "max_wss", "min_wss")
            if float(x[key]) != pytest.approx(float(y[key]), rel=1e-9)
        ]
    assert not any(comm.allgather(problems)), comm.allgather(problems)  # every rank ran alone


# --------------------------------------------------------------------------------------------
# Coupled moving wall


@pytest.fixture(scope="module")
def coupled():
    """Per acceleration: 2 steps straight; 1 step, then a restart into a new folder."""
    comm = MPI.COMM_WORLD
    path = Path(comm.bcast(tempfile.mkdtemp(prefix="fsi-test-") if comm.rank == 0 else None))
    runs = {}
    for name, overrides in ACCELERATIONS.items():
        straight, first, second = (path / name / n for n in ("straight", "first", "second"))
        codes = [
            fsi_run(COUPLED, straight, [*COUPLED_SET, *overrides, "time.end=0.002"]),
            fsi_run(COUPLED, first, [*COUPLED_SET, *overrides, "time.end=0.001"]),
        ]
        first_state = stored(first)
        codes.append(
            fsi_run(COUPLED, second, [*COUPLED_SET, *overrides, "time.end=0.002"], restart=first)
        )
        runs[name] = {
            "codes": codes,
            "straight": straight,
            "first": first,
            "second": second,
            "first_state": first_state,
        }
    yield runs
    comm.barrier()
    if comm.rank == 0:
        shutil.rmtree(path, ignore_errors=True)


@pytest.mark.parametrize("acceleration", list(ACCELERATIONS))
def test_coupled_restart_continues_like_the_uninterrupted_run(coupled, acceleration):
    run = coupled[acceleration]
    assert run["codes"] == [0, 0, 0]
    assert [r["step"] for r in rows(run["second"])] == ["1", "2"]  # row 1 copied over
    assert_same_rows(run["second"], run["straight"])
    assert_same_state(run["second"], run["straight"])
    s, r = summary(run["straight"]), summary(run["second"])
    for key in (
        "steps",
        "coupling_iterations",
        "max_coupling_iterations",
        "solid_newton_iterations",
        "newton_iterations",
    ):
        assert r[key] == s[key], key
    # What step 2 reuses was in the checkpoint: Aitken's ω; IQN-ILS: step 1's columns.
    saved = run["first_state"]
    if acceleration == "aitken":
        assert 0 < float(saved["coupling.aitken.omega"][1]) <= 1
    else:
        assert int(saved["coupling.iqn.steps"][1]) == 1
        keys, columns = saved["coupling.iqn.V.0"]
        block = 4 if acceleration == "robin-neumann" else 2  # x, y (and f_x, f_y)
        assert columns.shape[:2] == (len(keys), block)  # (interface nodes, values, columns)
        assert columns.shape[2] >= 3  # step 1 takes ≥ 4 iterations (measured 6)


def test_a_restart_that_changes_the_mesh_motion_warns(coupled, shared_tmp, capsys):
    """Changing mesh_motion at a restart is allowed, but the re-extended mesh jumps: say so."""
    first = coupled["aitken"]["first"]
    overrides = [*COUPLED_SET, *ACCELERATIONS["aitken"], "time.end=0.002"]
    changed = [*overrides, "mesh_motion.stiffening=distance"]
    assert fsi_run(COUPLED, shared_tmp / "changed", changed, restart=first) == 0
    err = stderr(capsys)
    assert "mesh_motion.stiffening differ from the run being continued" in err
    assert fsi_run(COUPLED, shared_tmp / "same", overrides, restart=first) == 0
    assert "differ from the run being continued" not in stderr(capsys)


@pytest.mark.parametrize(
    "failure, checkpointed",
    [
        # The mesh guard raises inside the coupling iteration of step 2 (solvers not restored).
        ("mesh_motion.min_jacobian_ratio=0.998", 1),
        # One coupling iteration is too few for step 1: the checkpoint is the initial state.
        ("coupling.max_iterations=1", 0),
    ],
)
def test_failed_step_is_checkpointed_and_a_restart_finishes_it(
    coupled, shared_tmp, fsi_log, failure, checkpointed
):
    out = shared_tmp / "failed"
    overrides = [*COUPLED_SET, *ACCELERATIONS["aitken"], "time.end=0.002"]
    assert fsi_run(COUPLED, out, [*overrides, failure]) == 3
    assert step_of(out) == checkpointed
    assert len(rows(out)) == checkpointed
    assert not (out / "summary.json").exists()
    if checkpointed == 1:  # the state after step 1, not the failed step's iterates
        assert_same_state(out, coupled["aitken"]["first"])
    text = MPI.COMM_WORLD.bcast(fsi_log.text)  # rank 0 logs
    assert f"checkpointed in {out / 'checkpoint'}" in text
    assert f"--out {out} --restart {out}" in text
    # The same folder, the failing setting dropped: finishes like the uninterrupted run.
    assert fsi_run(COUPLED, out, overrides, restart=out) == 0
    assert_same_rows(out, coupled["aitken"]["straight"])
    assert_same_state(out, coupled["aitken"]["straight"])


def test_structure_alone_restart_continues_like_the_uninterrupted_run(shared_tmp):
    """The structure under the inlet pressure (the generalized-α history η, η̇, η̈, loads)."""
    overrides = ["structure.interface_load=inlet_pressure", *COUPLED_SET]
    straight, split = shared_tmp / "straight", shared_tmp / "split"
    assert fsi_run(COUPLED, straight, [*overrides, "time.end=0.002"]) == 0
    assert fsi_run(COUPLED, split, [*overrides, "time.end=0.001"]) == 0
    assert fsi_run(COUPLED, split, [*overrides, "time.end=0.002"], restart=split) == 0
    assert_same_rows(split, straight)
    assert_same_state(split, straight)
    assert (split / "solid.restart1.xdmf").exists()


def test_an_adaptive_coupled_run_restarts_exactly(shared_tmp):
    """Adaptive steps (time.step_control: adaptive) of the coupled moving wall: stopped at a
    report time (both runs end a step there) and restarted, the run takes the same steps with
    the same rows and state as the uninterrupted one: the checkpoint holds the local error's
    levels of the velocity and the displacement and the size of the next step."""
    overrides = [
        *COUPLED_SET,
        "time.schedule=[{until: 0.003, dt: 1.0e-3}]",
        "time.step_control=adaptive",
        "time.adaptive={tolerance: 1.0e-3, first_dt: 2.5e-4, velocity_scale: 0.3, "
        "displacement_scale: 2.4e-4}",
        "output.report_times=[0.0015]",
    ]
    straight, split = shared_tmp / "straight", shared_tmp / "split"
    assert fsi_run(COUPLED, straight, [*overrides, "time.end=0.003"]) == 0
    assert fsi_run(COUPLED, split, [*overrides, "time.end=0.0015"]) == 0
    assert fsi_run(COUPLED, split, [*overrides, "time.end=0.003"], restart=split) == 0
    # On 2 ranks the estimate, a difference of fields ~1e3 times larger, carries their round-off
    # (~1e-12 relative) at ~1e-9 of itself (measured 2.5e-9), and so the steps' sizes at
    # ~1e-9 and every value after them: bounded by 1e-6 there; values near 0 to 1e-9 absolute
    # (the residual norms of converged iterates, ~1e-7 of their scale 1, measured 1.5e-12 apart
    # on dolfinx 0.9, also pass the helper's RESIDUAL_REL: see the top).
    assert_same_rows(split, straight, rel=1e-6, absolute=1e-9)
    assert_same_state(split, straight, rel=1e-6)
    taken = rows(straight)
    assert any(r["t"] == "0.0015" for r in taken) and taken[-1]["t"] == "0.003"
    dts = {float(r["dt"]) for r in taken}
    assert len(dts) > 2, dts  # the steps did change size
    assert "time_error.structure.values" in stored(split)
    # The third step (the first with an estimate) was too long: measured rejected twice.
    assert summary(straight)["rejected_steps"] == [3]


# --------------------------------------------------------------------------------------------
# Checkpoints that do not fit are refused before any work (exit 2)


def copy_checkpoint(rigid, shared_tmp) -> Path:
    """A run folder with the split run's checkpoint (step 6) and the metrics.csv it keeps."""
    source = shared_tmp / "source"
    if MPI.COMM_WORLD.rank == 0:
        shutil.copytree(rigid["split"] / "checkpoint", source / "checkpoint")
        shutil.copy(rigid["split"] / "metrics.csv", source / "metrics.csv")
    MPI.COMM_WORLD.barrier()
    return source


@pytest.mark.parametrize(
    "overrides, expected",
    [
        (["mesh.level=fine"], "mesh.level: the checkpoint has 'coarse', the configuration 'fine'"),
        (["structure.mode=moving_wall"], "structure.mode: the checkpoint has 'rigid'"),
        (["geometry.stenosis_degree=0.6"], "geometry.stenosis_degree: the checkpoint has 0.5"),
    ],
)
def test_a_checkpoint_of_another_setup_is_refused(rigid, shared_tmp, capsys, overrides, expected):
    out = shared_tmp / "refused"
    split = rigid["split"]
    assert fsi_run(RIGID, out, [*RIGID_SET, "time.end=0.004", *overrides], restart=split) == 2
    assert not out.exists()
    err = stderr(capsys)
    assert expected in err
    assert str(split / "checkpoint" / "checkpoint.json") in err


def test_a_missing_or_damaged_checkpoint_is_refused(rigid, shared_tmp, capsys):
    comm = MPI.COMM_WORLD
    out = shared_tmp / "refused"
    overrides = [*RIGID_SET, "time.end=0.004"]
    assert fsi_run(RIGID, out, overrides, restart=shared_tmp / "nowhere") == 2
    assert str(shared_tmp / "nowhere" / "checkpoint" / "checkpoint.json") in stderr(capsys)
    # A rank file cut short: every rank stops, naming it.
    source = copy_checkpoint(rigid, shared_tmp)
    damaged = source / "checkpoint" / checkpoint.rank_file(comm.size - 1)
    if comm.rank == 0:
        damaged.write_bytes(damaged.read_bytes()[:1000])
    comm.barrier()
    assert fsi_run(RIGID, out, overrides, restart=source) == 2
    assert f"{damaged}: unreadable checkpoint" in stderr(capsys)
    assert not out.exists()


def test_a_checkpoint_of_another_mesh_is_refused_before_writing(rigid, shared_tmp, capsys):
    """checkpoint.json agrees, the keys of the velocity nodes do not (as for another mesh):
    caught while the state is given to this run's dofs, before any file is written."""
    comm = MPI.COMM_WORLD
    source = copy_checkpoint(rigid, shared_tmp)
    if comm.rank == 0:
        path = source / "checkpoint" / checkpoint.rank_file(0)
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
        arrays["keys.fluid_velocity"] = arrays["keys.fluid_velocity"] + 1e-7  # 0.1 µm
        with path.open("wb") as f:
            np.savez(f, **arrays)
    comm.barrier()
    out = shared_tmp / "refused"
    assert fsi_run(RIGID, out, [*RIGID_SET, "time.end=0.004"], restart=source) == 2
    assert not out.exists()
    err = stderr(capsys)
    assert "fluid_velocity: " in err and "dofs of this run are not in the checkpoint" in err


def test_a_restart_cannot_shorten_the_run(rigid, shared_tmp, capsys):
    """The split run's checkpoint is at t = 4 ms: a restart ending at 3 ms is refused, in its
    own folder too, which is left as it was (its config.yaml keeps the 4 ms end); ending at
    4 ms (nothing left to do: a run stopped before its summary) is allowed."""
    split = rigid["split"]
    out = shared_tmp / "shorter"
    assert fsi_run(RIGID, out, [*RIGID_SET, "time.end=0.003"], restart=split) == 2
    assert "the checkpoint is at t = 0.004 s, after the configuration's end (0.003 s)" in (
        stderr(capsys)
    )
    assert not out.exists()
    source = copy_checkpoint(rigid, shared_tmp)
    if MPI.COMM_WORLD.rank == 0:
        shutil.copy(split / "config.yaml", source / "config.yaml")
    MPI.COMM_WORLD.barrier()
    before = (source / "config.yaml").read_text()
    assert fsi_run(RIGID, source, [*RIGID_SET, "time.end=0.003"], restart=source) == 2
    assert "cannot shorten it (raise time.end)" in stderr(capsys)
    assert (source / "config.yaml").read_text() == before
    assert fsi_run(RIGID, source, [*RIGID_SET, "time.end=0.004"], restart=source) == 0


def test_a_restart_with_another_heartbeat_period_is_refused(shared_tmp, capsys):
    """A run with a periodic inlet (period 2 ms), 2 steps; a restart with period 2.5 ms would
    put the heartbeats of the rows and indices already written elsewhere: refused, naming the
    key and both periods; the same period continues."""

    def inlet(period: float) -> str:
        table = "[[0.0, 0.0], [0.001, 100.0], [0.0025, 0.0]]"
        return f"fluid.inlet={{kind: pressure_table, table: {table}, period: {period}}}"

    steps = ["structure.mode=rigid", "time.schedule=[{until: 0.004, dt: 0.001}]", EVERY_STEP]
    run = shared_tmp / "periodic"
    assert fsi_run(RIGID, run, [*steps, inlet(0.002), "time.end=0.002"]) == 0
    out = shared_tmp / "other_period"
    assert fsi_run(RIGID, out, [*steps, inlet(0.0025), "time.end=0.004"], restart=run) == 2
    err = stderr(capsys)
    assert "fluid.inlet.period: the run being continued has 0.002 s" in err
    assert "the configuration 0.0025 s" in err
    assert not out.exists()
    assert fsi_run(RIGID, run, [*steps, inlet(0.002), "time.end=0.004"], restart=run) == 0
    assert [int(r["cycle"]) for r in rows(run)] == [1, 1, 2, 2]


# --------------------------------------------------------------------------------------------
# A checkpoint's contents and the rows it keeps are checked before anything is written (exit 2)


LAST = MPI.COMM_WORLD.size - 1  # the rank file of the last rank
JSON = "{source}/checkpoint/checkpoint.json"
METRICS = "{source}/metrics.csv"


def edit_json(**changes):
    def edit(source: Path) -> None:
        path = source / "checkpoint" / "checkpoint.json"
        path.write_text(json.dumps({**json.loads(path.read_text()), **changes}))

    return edit


def edit_array(key: str, change, rank: int = 0):
    def edit(source: Path) -> None:
        path = source / "checkpoint" / checkpoint.rank_file(rank)
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
        arrays[key] = change(arrays[key])
        with path.open("wb") as f:
            np.savez(f, **arrays)

    return edit


def edit_metrics(change):
    """``change`` maps the lines of metrics.csv (header first, with their line ends) to new
    ones."""

    def edit(source: Path) -> None:
        path = source / "metrics.csv"
        path.write_bytes(b"".join(change(path.read_bytes().splitlines(keepends=True))))

    return edit


def with_nan(a: np.ndarray) -> np.ndarray:
    a = a.astype(float)
    a.flat[a.size // 2] = np.nan
    return a


def listing(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


# The split run's checkpoint: step 6, t = 4 ms, dt = 0.5 ms; metrics.csv has steps 1–6 at
# t = 1, 2, 2.5, 3, 3.5, 4 ms (step n on line n + 1).
@pytest.mark.parametrize(
    "edit, expected",
    [
        (edit_json(step="6"), JSON + ": step: expected a whole number >= 0, got '6'"),
        (edit_json(step=-1), JSON + ": step: expected a whole number >= 0, got -1"),
        (edit_json(step=6.0), JSON + ": step: expected a whole number >= 0, got 6.0"),
        (edit_json(t=-0.004), JSON + ": t: expected a finite time >= 0 (0 at step 0), got -0.004"),
        (
            edit_json(t=float("nan")),
            JSON + ": t: expected a finite time >= 0 (0 at step 0), got nan",
        ),
        (edit_json(step=0), JSON + ": t: expected a finite time >= 0 (0 at step 0), got 0.004"),
        (edit_json(dt=0.0), JSON + ": dt: expected null or a finite step > 0, got 0.0"),
        (edit_json(dt=float("inf")), JSON + ": dt: expected null or a finite step > 0, got inf"),
        (edit_json(files=["../rank0000.npz"]), JSON + ": files: expected rank0000.npz to "),
        # Step and time that contradict metrics.csv.
        (
            edit_json(step=4),
            JSON + ": t: the checkpoint has 0.004, but " + METRICS + " line 5 "
            "(step 4) has t = 0.003",
        ),
        (
            edit_json(t=0.0041),
            JSON + ": t: the checkpoint has 0.0041, but " + METRICS + " line 7 "
            "(step 6) has t = 0.004",
        ),
        (
            edit_json(dt=0.001),
            JSON + ": dt: the checkpoint has 0.001, but " + METRICS + " line 7 "
            "(step 6) has dt = 0.0005",
        ),
        (
            edit_json(step=9),
            METRICS + ": no row of steps 7-9: the table was cut short or damaged, "
            "and a restart from step 9 keeps its rows 1 to 9",
        ),
        # The arrays.
        (
            edit_array("fluid.U", with_nan, rank=LAST),
            f"{{source}}/checkpoint/{checkpoint.rank_file(LAST)}: fluid.U: non-finite values",
        ),
        (
            edit_array("fluid.time", lambda a: a * np.inf),
            "{source}/checkpoint/rank0000.npz: fluid.time: non-finite values",
        ),
        (
            edit_array("fluid.time", lambda a: 2 * a),
            "{source}/checkpoint/rank0000.npz: fluid.time: 0.008, but checkpoint.json's t is 0.004",
        ),
        (
            edit_array("fluid.dt_previous", lambda a: a.astype("U8")),
            "{source}/checkpoint/rank0000.npz: fluid.dt_previous: expected numbers",
        ),
        (
            edit_array("fluid.u_n", lambda a: a[1:]),
            "{source}/checkpoint/rank0000.npz: array 'fluid.u_n' has shape ",
        ),
    ],
)
def test_a_damaged_or_edited_checkpoint_is_refused_before_writing(
    rigid, shared_tmp, capsys, edit, expected
):
    source = copy_checkpoint(rigid, shared_tmp)
    if MPI.COMM_WORLD.rank == 0:
        edit(source)
    MPI.COMM_WORLD.barrier()
    out = shared_tmp / "refused"
    assert fsi_run(RIGID, out, [*RIGID_SET, "time.end=0.004"], restart=source) == 2
    assert not out.exists()
    err = stderr(capsys)
    assert f"fsi: error: --restart: {expected.format(source=source)}" in err
    assert "Traceback" not in err


def drop(*steps: int):
    return edit_metrics(lambda lines: [x for i, x in enumerate(lines) if i not in steps])


@pytest.mark.parametrize(
    "edit, expected",
    [
        # Cut short after step 3, or a row lost: the gap is named, nothing is kept or written.
        (
            edit_metrics(lambda lines: lines[:4]),
            METRICS + ": no row of steps 4-6: the table was cut "
            "short or damaged, and a restart from step 6 keeps its rows 1 to 6",
        ),
        (edit_metrics(lambda lines: lines[:4] + [lines[4][:9]]), METRICS + ": no row of steps 4-6"),
        (drop(2), METRICS + ": no row of step 2: "),
        (drop(1, 2, 3, 4, 5, 6), METRICS + ": no row of steps 1-6: "),
        (
            lambda source: (source / "metrics.csv").unlink(),
            METRICS + ": missing; a restart from step 6 keeps its rows 1 to 6",
        ),
        (
            edit_metrics(lambda lines: lines[:4] + [lines[3]] + lines[4:]),
            METRICS + ": line 5: step 3 where step 4 belongs",
        ),
        (
            edit_metrics(
                lambda lines: lines[:2] + [lines[2].replace(b",0.002,", b",0.0o2,")] + lines[3:]
            ),
            METRICS
            + ": line 3: t: '0.0o2' is not a finite number (a restart from step 6 keeps its "
            "rows 1 to 6)",
        ),
        (
            edit_metrics(lambda lines: lines[:3] + [b"4,0.003\r\n"] + lines[5:]),
            METRICS + ": line 4: 2 cells, the header has ",
        ),
    ],
)
def test_a_restart_refuses_a_damaged_metrics_table_and_keeps_it(
    rigid, shared_tmp, capsys, edit, expected
):
    """metrics.csv must hold rows 1 to k, complete, each once, for a restart from step k to
    keep; otherwise exit 2 before anything is written (restarting in the run's own folder: not
    a byte of it changes)."""
    source = copy_checkpoint(rigid, shared_tmp)
    if MPI.COMM_WORLD.rank == 0:
        edit(source)
    MPI.COMM_WORLD.barrier()
    before = listing(source)
    assert fsi_run(RIGID, source, [*RIGID_SET, "time.end=0.004"], restart=source) == 2
    err = stderr(capsys)
    assert f"fsi: error: --restart: {expected.format(source=source)}" in err
    assert "Traceback" not in err
    assert listing(source) == before


def test_a_row_cut_short_after_the_checkpoint_is_dropped(rigid, shared_tmp, fsi_log):
    """A run killed while writing row 7 (its checkpoint: step 6) continues from step 6: the
    partial row is replaced by the new step 7, rows 1–6 are kept as they were."""
    source = copy_checkpoint(rigid, shared_tmp)
    kept = (source / "metrics.csv").read_bytes()
    if MPI.COMM_WORLD.rank == 0:
        (source / "metrics.csv").write_bytes(kept + b"7,0.0045,0.0005,0.3")
    MPI.COMM_WORLD.barrier()
    longer = "time.schedule=[{until: 0.002, dt: 0.001}, {until: 0.0045, dt: 0.0005}]"
    assert fsi_run(RIGID, source, [*RIGID_SET, longer, "time.end=0.0045"], restart=source) == 0
    table = (source / "metrics.csv").read_bytes()
    assert table.startswith(kept)
    assert [r["step"] for r in rows(source)] == ["1", "2", "3", "4", "5", "6", "7"]
    assert rows(source)[-1]["peak_velocity"] != "0.3"
    assert not (source / "metrics.csv.partial").exists()


# --------------------------------------------------------------------------------------------
# The files: atomic replacement


def test_a_checkpoint_is_replaced_atomically(shared_tmp):
    comm = MPI.COMM_WORLD
    case = config.load(RIGID, [*RIGID_SET, "time.end=0.004"])
    out = shared_tmp / "atomic"
    if comm.rank == 0:  # the run folder: its metrics.csv has the rows a restart keeps
        out.mkdir()
        (out / "metrics.csv").write_text(
            "step,t,dt\n" + "".join(f"{k},{1e-3 * k},0.001\n" for k in (1, 2, 3))
        )
    comm.barrier()
    # One row per rank, keyed by the rank: after reading, each rank finds its own value.
    layouts = {"x": state_arrays.Layout("ranks", np.array([[float(comm.rank)]]), 1, 1)}

    def save(step: int) -> None:
        checkpoint.write(
            out,
            comm,
            {"x": np.array([step + comm.rank / 10])},
            layouts,
            checkpoint_checks.metadata(case, comm, step, 1e-3 * step, 1e-3),
        )

    def load() -> list:
        """(run folder right, step, value) of every rank: the asserts stay collective."""
        found = checkpoint.read(out, case, comm)
        value = float(checkpoint.localize(found, layouts, {}, comm)["x"][0])
        return comm.allgather((found.run_dir == out, found.step, value))

    def expected(step: int) -> list:
        return [(True, step, step + rank / 10) for rank in range(comm.size)]

    def listing() -> list:
        return comm.allgather(sorted(p.name for p in out.iterdir()))

    save(1)
    assert load() == expected(1)
    # Killed while writing the next one: the half-written folder is ignored, then replaced.
    if comm.rank == 0:
        (out / "checkpoint.partial").mkdir()
        (out / "checkpoint.partial" / "rank0000.npz").write_bytes(b"PK\x03\x04 cut")
    comm.barrier()
    assert load() == expected(1)
    save(2)
    assert load() == expected(2)
    assert listing() == [["checkpoint", "metrics.csv"]] * comm.size
    # Killed between the two renames: the previous complete checkpoint is used.
    if comm.rank == 0:
        (out / "checkpoint").rename(out / "checkpoint.previous")
    comm.barrier()
    assert load() == expected(2)
    # A non-finite value is never written.
    with pytest.raises(checkpoint.CheckpointError, match="non-finite x"):
        checkpoint.write(
            out,
            comm,
            {"x": np.array([np.nan])},
            layouts,
            checkpoint_checks.metadata(case, comm, 3, 3e-3, 1e-3),
        )
    assert load() == expected(2)
    assert listing() == [["checkpoint.previous", "metrics.csv"]] * comm.size


def test_state_dataclasses_round_trip_through_arrays():
    from fsi.physics.fluid import FluidState

    s = FluidState(0.25, None, 3, *(np.arange(4.0) + i for i in range(7)), True)
    back = state_arrays.from_arrays(FluidState, "fluid.", state_arrays.to_arrays("fluid.", s))
    assert back.dt_previous is None and back.time == 0.25 and back.accepted_steps == 3
    assert back.mesh_velocity_given is True and np.array_equal(back.w, s.w)
    s2 = FluidState(0.5, 1e-3, 4, *(np.arange(4.0) for _ in range(7)), False)
    assert (
        state_arrays.from_arrays(FluidState, "", state_arrays.to_arrays("", s2)).dt_previous == 1e-3
    )


@pytest.mark.parametrize("acceleration", ["aitken", "iqn-ils"])
def test_coupling_memory_carries_over_through_its_arrays(acceleration):
    """Aitken's ω, IQN-ILS's past columns and the predictor's history, saved after step 2 of a
    linear fixed-point problem x = A x + b(t) and loaded into fresh objects: step 3 repeats bit
    for bit (and without them it takes another path)."""
    from fsi.coupled import coupling

    comm = MPI.COMM_SELF
    rng = np.random.default_rng(1)
    A = -0.9 * np.eye(8) + 0.05 * rng.standard_normal((8, 8))  # added-mass-like: |λ| ≈ 0.9

    def build():
        if acceleration == "aitken":
            return coupling.Aitken(comm, 0.5), coupling.Predictor(2)
        return coupling.IQNILS(comm, 0.5, reuse=2), coupling.Predictor(2)

    def step(acc, predictor, t):
        x, history = predictor.predict(t), []
        acc.start_step()
        for _ in range(100):
            x_tilde = A @ x + np.sin(t + np.arange(8))
            history.append(x_tilde)
            if coupling.relative_residual(comm, x, x_tilde) < 1e-10:
                acc.end_step()
                predictor.record(x_tilde, t)
                return history
            x = acc.next_input(x, x_tilde)
        raise AssertionError("no convergence")

    acc, predictor = build()
    predictor.record(np.zeros(8), 0.0)
    for t in (0.1, 0.2):
        step(acc, predictor, t)
    saved = {**acc.state(), **{f"p.{k}": v for k, v in predictor.state().items()}}
    again, fresh = build(), build()
    again[0].load_state(saved)
    again[1].load_state(state_arrays.subset("p.", saved))
    fresh[1].load_state(state_arrays.subset("p.", saved))
    expected, repeated, without = (step(*pair, 0.3) for pair in ((acc, predictor), again, fresh))
    assert len(expected) == len(repeated) and all(
        np.array_equal(a, b) for a, b in zip(expected, repeated)
    )
    assert len(without) != len(expected) or not np.array_equal(without[1], expected[1])


# --------------------------------------------------------------------------------------------
# A restart continues the run's own configuration


def test_a_restart_continues_the_runs_own_configuration(shared_tmp, capsys):
    """A run made with ``--set`` of its inlet: ``fsi run --restart RUN`` without a case file
    continues it with its own config.yaml (``--set`` changes only what it names); with the case
    file, whose inlet differs, it is refused, naming the keys, and nothing is changed, unless
    ``--allow-changes``; without a case file or ``--restart``, ``fsi run`` says what it needs."""
    steps = ["structure.mode=rigid", "time.schedule=[{until: 0.004, dt: 0.001}]", EVERY_STEP]
    inlet = "fluid.inlet={kind: pressure, formula: '300*sin(pi*t/0.004)**2'}"
    run = shared_tmp / "own"
    assert fsi_run(RIGID, run, [*steps, inlet, "time.end=0.002"]) == 0
    before = {name: (run / name).read_text() for name in ("config.yaml", "metrics.csv")}

    more = ["--set", "time.end=0.003"]
    rigid = ["--set", "structure.mode=rigid"]
    capsys.readouterr()
    assert cli.main(["run", RIGID, "--out", str(run), "--restart", str(run), *more, *rigid]) == 2
    err = stderr(capsys)
    assert f"--restart: {RIGID} (with --set) differs from the run being continued" in err
    assert f"({run / 'config.yaml'}) in fluid.inlet.kind" in err, err
    assert f"fsi run --restart {run} --out {run}), or add --allow-changes" in err
    assert {name: (run / name).read_text() for name in before} == before

    assert cli.main(["run", "--out", str(run), "--restart", str(run), *more]) == 0
    assert config.load(run / "config.yaml").fluid.inlet == config.load(RIGID, [inlet]).fluid.inlet
    assert [r["step"] for r in rows(run)] == ["1", "2", "3"]

    assert cli.main(["run", RIGID, "--out", str(run), "--restart", str(run), *rigid,
                     "--set", "time.end=0.004", "--allow-changes"]) == 0  # fmt: skip
    assert config.load(run / "config.yaml").fluid.inlet.kind == "traction_pulse"
    capsys.readouterr()
    assert cli.main(["run", "--out", str(shared_tmp / "none")]) == 2
    assert "fsi run: a case file is needed, or --restart DIR" in stderr(capsys)
    assert not (shared_tmp / "none").exists()


def test_a_runs_own_configuration_loads_whatever_its_inlet_table(shared_tmp):
    """A CSV inlet near the case-file limit is written into config.yaml as a table that is
    larger than a case file may be: the run's own file still loads (report, restart)."""
    rows_ = [[i * 1e-5, 100.0 + (i % 7) * 1.234567] for i in range(60_000)]
    case = config.from_dict({"fluid": {"inlet": {"kind": "pressure_table", "table": rows_}}})
    path = shared_tmp / f"config{MPI.COMM_WORLD.rank}.yaml"
    config.dump(case, path)
    assert path.stat().st_size > config.case_file.MAX_FILE_BYTES
    with pytest.raises(config.ConfigError, match="larger than"):
        config.load(path)
    assert config.load(path, run_config=True).fluid.inlet.table[-1] == tuple(rows_[-1])
