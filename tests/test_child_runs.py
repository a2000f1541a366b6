"""The one environment of a child ``fsi run`` or ``mpirun`` (fsi/run/child_runs.py's
``environment``): Python's copy of the environment, Open MPI's permission to run as root when
root, the single-copy transfers off unless chosen; and every launcher of such children (the
study's reruns, the speed study's workers, ``child_runs.run``) hands it over."""

import argparse
import os
import subprocess
from pathlib import Path

import pytest

from fsi.performance import study_speed
from fsi.run import child_runs
from fsi.study import reproduce

ROOT = Path(__file__).resolve().parents[1]
ROOT_PERMISSION = ("OMPI_ALLOW_RUN_AS_ROOT", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM")


def test_the_environment_is_pythons_copy_with_the_single_copy_transfers_off(monkeypatch):
    monkeypatch.setenv("FSI_CHILD_MARK", "kept")
    monkeypatch.delenv(child_runs.SINGLE_COPY, raising=False)
    env = child_runs.environment()
    assert env["FSI_CHILD_MARK"] == "kept"
    assert env[child_runs.SINGLE_COPY] == "none"
    monkeypatch.setenv(child_runs.SINGLE_COPY, "cma")  # the environment's own choice stands
    assert child_runs.environment()[child_runs.SINGLE_COPY] == "cma"


@pytest.mark.parametrize("uid", [0, 1000])
def test_root_is_allowed_only_when_root(monkeypatch, uid):
    for name in ROOT_PERMISSION:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(os, "geteuid", lambda: uid)
    env = child_runs.environment()
    assert all(env.get(name) == ("1" if uid == 0 else None) for name in ROOT_PERMISSION)


def _capture(monkeypatch, name: str) -> list[dict]:
    """Replace ``subprocess.<name>`` by a recorder of the ``env`` it is given (the child
    "fails", exit 1, without running)."""
    seen: list[dict] = []

    def fake(*args, env=None, **kwargs):
        seen.append(env)
        return subprocess.CompletedProcess(args, 1, "", "not run")

    monkeypatch.setattr(subprocess, name, fake)
    return seen


def test_every_launcher_hands_its_children_the_one_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("FSI_CHILD_MARK", "launched")
    expected = child_runs.environment()

    calls = _capture(monkeypatch, "call")
    run = reproduce.StudyRun("stenosis_fixed_newtonian", "coarse", label="probe", end=0.01)
    reproduce.run_all([run], tmp_path / "study", ranks=2)
    assert calls == [expected]

    runs = _capture(monkeypatch, "run")
    args = argparse.Namespace(config=study_speed.CASE, overrides=[])
    for ranks in (1, 2):
        assert study_speed.launch(args, "coarse", "coupled", ranks, "1")["failure"]
    config = ROOT / "configs" / "stenosis_fixed_newtonian.yaml"
    child_runs.run(config, tmp_path / "child", [], ranks=2)
    assert runs == [expected] * 3


def test_no_other_module_builds_the_child_environment_by_hand():
    """The root permission and the single-copy switch are written in child_runs alone (but in
    the shell lines of fsi/run/slurm.py's batch script, which a cluster node runs, not a child
    of this process)."""
    written = [
        str(p.relative_to(ROOT))
        for p in (ROOT / "fsi").rglob("*.py")
        if p.name not in ("child_runs.py", "slurm.py")
        and any(name in p.read_text() for name in (*ROOT_PERMISSION, child_runs.SINGLE_COPY))
    ]
    assert written == []
