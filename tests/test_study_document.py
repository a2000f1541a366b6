"""scripts/study_document.py: the verdicts on the study's findings and the tables of docs/study.md
are comparisons of the runs' numbers (synthetic runs here, whose answers are known)."""

import sys
from pathlib import Path

import pytest

from fsi import config
from fsi.output import report

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from scripts import study_document  # noqa: E402

TIMES = [0.0025, 0.005, 0.01, 0.02, 0.05, 0.1, 0.8]


def run(
    name: str, sss: float, displacement: float = 1e-6, recirculation: float = 6e-3, end: float = 0.8
) -> report.Run:
    """A run whose columns are constant in time (their maxima are the values given)."""
    rows = [
        {
            "step": i + 1,
            "t": t,
            "dt": 1e-3,
            "max_sss": sss,
            "peak_velocity": 0.2,
            "peak_pressure": 1000.0,
            "peak_displacement": displacement,
            "recirculation_length": recirculation,
            "min_wss": -1.0,
            "max_wss": 5.0,
        }
        for i, t in enumerate(TIMES)
        if t <= end
    ]
    return report.Run(Path(name), config.Case(), rows, {"steps": len(rows)})


def verdicts(runs: dict) -> list[str]:
    return [f.split(" — ")[1].split(" (")[0] for f in study_document.findings(runs)]


def test_the_study_s_findings_confirmed():
    runs = {
        "fixed_newtonian_coarse": run("a", 300.0),
        "fixed_carreau_coarse": run("b", 290.0),
        "moving_newtonian_coarse": run("c", 20000.0, 2e-4),
        "moving_carreau_coarse": run("d", 10000.0, 1e-4),
    }
    assert verdicts(runs) == ["confirmed", "confirmed", "confirmed"]


def test_the_study_s_findings_refuted():
    runs = {
        "fixed_newtonian_coarse": run("a", 300.0, recirculation=3e-3),
        "fixed_carreau_coarse": run("b", 400.0),
        "moving_newtonian_coarse": run("c", 10000.0, 1e-4),
        "moving_carreau_coarse": run("d", 10000.0, 1e-4),
    }
    assert verdicts(runs) == ["refuted", "refuted", "refuted"]


def test_the_findings_use_the_fine_mesh_once_its_four_runs_finished():
    coarse = {f"{c}_coarse": run(f"{c}_coarse", 300.0) for c in study_document.CONFIGS}
    fine = {f"{c}_fine": run(f"{c}_fine", 500.0) for c in study_document.CONFIGS}
    assert "(fixed_newtonian_fine)" in study_document.findings({**coarse, **fine})[0]
    fine["fixed_carreau_fine"] = run("fixed_carreau_fine", 500.0, end=0.1)  # unfinished
    assert "(fixed_newtonian_coarse)" in study_document.findings({**coarse, **fine})[0]


def test_the_peak_tables_give_coarse_fine_and_their_change():
    runs = {
        "fixed_newtonian_coarse": run("a", 1.0, displacement=2e-6),
        "fixed_newtonian_fine": run("b", 1.0, displacement=3e-6),
    }
    table = study_document.peak_table(runs, "peak_displacement", "µm", 1e6)
    row = next(line for line in table.splitlines() if line.startswith("| 0.01 |"))
    assert row.startswith("| 0.01 | 2 | 3 | +50.0 % | – | – | – |")


@pytest.mark.parametrize(
    "coarse,fine,expected", [(2.0, 3.0, "+50.0 %"), (2.0, None, "–"), (0.0, 1.0, "–")]
)
def test_change(coarse, fine, expected):
    assert study_document.change(coarse, fine) == expected
