"""The accuracy test of a speed setting (fsi/performance/accuracy.py, issue #46): the reference's
settings, the errors against it at the compared times, the verdicts, and the command on run
folders made here (the arithmetic) and, slow, on real runs."""

from __future__ import annotations

import json
from pathlib import Path

from mpi4py import MPI

import pytest

from fsi import config
from fsi.performance import accuracy

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "configs/stenosis_moving_newtonian.yaml"


def test_the_reference_quarters_every_step_and_tightens_the_tolerances():
    case = config.load(STUDY)
    reference = config.load(STUDY, accuracy.reference_overrides(case))
    assert [s.until for s in reference.time.schedule] == [s.until for s in case.time.schedule]
    for ours, theirs in zip(reference.time.schedule, case.time.schedule):
        assert ours.dt == pytest.approx(theirs.dt / 4, rel=1e-15)
    assert reference.coupling.tolerance == 1e-8 and reference.coupling.geometry == "implicit"
    assert reference.coupling.fluid_forcing == 0.0
    assert reference.fluid.solver.linearization == "newton"
    assert reference.fluid.solver.atol == 1e-12 and reference.structure.solver.atol == 1e-12


def _rows(times, **columns):
    return [
        {"step": i + 1, "t": t, **{c: f(t) for c, f in columns.items()}}
        for i, t in enumerate(times)
    ]


def test_errors_are_measured_at_the_compared_times_against_the_peak():
    """The reference's steps are quartered: the run's rows meet it at every fourth; the error of
    a column is its largest difference there over the reference's peak; the outlet's mean
    pressure (0 at a stress-free outlet) over the inlet's peak."""
    fine = [k * 0.25e-3 for k in range(1, 41)]
    coarse = fine[3::4]
    reference = _rows(
        fine, peak_velocity=lambda t: 100 * t, mean_inlet_pressure=lambda t: 1e5 * t,
        mean_outlet_pressure=lambda t: 0.0,
    )  # fmt: skip
    run = _rows(
        coarse, peak_velocity=lambda t: 100 * t + 0.01, mean_inlet_pressure=lambda t: 1e5 * t,
        mean_outlet_pressure=lambda t: 5.0,
    )  # fmt: skip
    e = accuracy.errors(run, reference)
    assert e["peak_velocity"] == pytest.approx(0.01 / 1.0)
    assert e["mean_inlet_pressure"] == pytest.approx(0.0, abs=1e-15)
    assert e["mean_outlet_pressure"] == pytest.approx(5.0 / 1000.0)
    with pytest.raises(ValueError, match="no step at t = 0.0101"):
        accuracy.errors(_rows([0.0101], peak_velocity=lambda t: 0.0), reference)


def test_a_candidate_may_be_as_accurate_as_the_shipped_scheme_not_more():
    shipped = {"peak_velocity": 0.02, "max_sss": 0.001}
    assert accuracy.verdicts(shipped, {"peak_velocity": 0.025, "max_sss": 0.005}) == {
        "peak_velocity": True,  # 1.25 × 2 %
        "max_sss": True,  # the 0.5 % floor
    }
    assert accuracy.verdicts(shipped, {"peak_velocity": 0.0251, "max_sss": 0.0051}) == {
        "peak_velocity": False,
        "max_sss": False,
    }


def _folder(path: Path, rows: list[dict]) -> None:
    path.mkdir(parents=True)
    header = list(rows[0])
    lines = [",".join(header)] + [",".join(repr(float(r[c])) for c in header) for r in rows]
    (path / "metrics.csv").write_text("\n".join(lines) + "\n")
    (path / "summary.json").write_text("{}")


def test_the_command_on_finished_runs(tmp_path, capsys):
    """``--reuse`` takes finished folders as they are: the table, the JSON line and the exit
    status (1: a candidate fails)."""
    fine = [k * 0.25e-3 for k in range(1, 21)]
    coarse = fine[3::4]
    _folder(tmp_path / "reference", _rows(fine, peak_velocity=lambda t: 100 * t))
    _folder(tmp_path / "shipped", _rows(coarse, peak_velocity=lambda t: 100 * t + 0.004))
    _folder(tmp_path / "good", _rows(coarse, peak_velocity=lambda t: 100 * t + 0.005))
    _folder(tmp_path / "bad", _rows(coarse, peak_velocity=lambda t: 100 * t + 0.02))
    args = [str(STUDY), "--out", str(tmp_path), "--reuse", "--set", "time.end=0.005"]
    status = accuracy.main([*args, "--candidate", "good", "", "--candidate", "bad", ""])
    out = capsys.readouterr().out
    result = json.loads(out.strip().splitlines()[-1])
    assert status == 1
    assert result["passes"] == {"good": {"peak_velocity": True}, "bad": {"peak_velocity": False}}
    assert result["errors"]["shipped"]["peak_velocity"] == pytest.approx(0.004 / 0.5)
    assert "| verdict | — | passes | fails |" in out


@pytest.mark.skipif(
    MPI.COMM_WORLD.size > 1, reason="launches fsi run (its own MPI); runs in the serial lane"
)
def test_a_candidate_whose_run_fails_fails(tmp_path, capsys):
    """A candidate that cannot finish (here its setting is refused, exit 2) fails in the table
    and the JSON line, and the others are still compared."""
    fine = [k * 0.25e-3 for k in range(1, 21)]
    _folder(tmp_path / "reference", _rows(fine, peak_velocity=lambda t: 100 * t))
    _folder(tmp_path / "shipped", _rows(fine[3::4], peak_velocity=lambda t: 100 * t + 0.004))
    args = [str(STUDY), "--out", str(tmp_path), "--reuse", "--set", "time.end=0.005"]
    status = accuracy.main([*args, "--candidate", "broken", "coupling.tolerance=-1"])
    out = capsys.readouterr().out
    assert status == 1
    assert json.loads(out.strip().splitlines()[-1])["passes"] == {"broken": {"finished": False}}
    assert "| peak_velocity | 0.800 % | — |" in out
    assert "| verdict | — | **fails** (the run failed) |" in out


@pytest.mark.slow
def test_the_extrapolated_fluid_on_the_pulse(tmp_path_factory):
    """The accuracy test run for real on the moving Newtonian case's first 5 ms (20 steps; the
    reference 80): the shipped scheme's errors are small (the pulse is resolved), every column
    has one, and the command ends with its verdicts."""
    out = tmp_path_factory.mktemp("accuracy")
    status = accuracy.main([str(STUDY), "--out", str(out), "--set", "time.end=0.005"])
    rows = (out / "shipped" / "metrics.csv").read_text().splitlines()
    assert len(rows) == 21 and status in (0, 1)


def test_a_candidate_with_its_own_schedule_is_compared_at_the_shipped_steps_it_took():
    """Finer in one stretch, coarser in another: only the times the shipped run also has are
    compared (the finer steps' extra rows are left out, the coarser ones' are all shipped)."""
    shipped = _rows([k * 0.25e-3 for k in range(1, 9)], peak_velocity=lambda t: 0.0)
    candidate = _rows(
        [k * 0.125e-3 for k in range(1, 9)] + [1.5e-3, 2.0e-3], peak_velocity=lambda t: 0.0
    )
    kept = accuracy.at_shipped_times(candidate, shipped)
    assert [r["t"] for r in kept] == pytest.approx([0.25e-3, 0.5e-3, 0.75e-3, 1.0e-3, 1.5e-3, 2e-3])


def test_a_candidate_may_carry_a_yaml_list_among_its_settings():
    """The candidate's K=V,K=V splits at the commas outside brackets and braces."""
    text = (
        "fluid.solver.linearization=extrapolated,"
        "time.schedule=[{until: 0.05, dt: 5.0e-4}, {until: 0.8, dt: 5.0e-3}],"
        " coupling.tolerance=1e-4"
    )
    assert accuracy.split_overrides(text) == (
        "fluid.solver.linearization=extrapolated",
        "time.schedule=[{until: 0.05, dt: 5.0e-4}, {until: 0.8, dt: 5.0e-3}]",
        "coupling.tolerance=1e-4",
    )
    assert accuracy.split_overrides("") == ()
