"""fsi/study/document.py: the verdicts on the study's findings and the tables of docs/study.md
are comparisons of the runs' numbers (synthetic runs here, whose answers are known), made from
the runs' summaries; docs/study_tables.csv holds the study's 120 printed values."""

import csv
import json
from pathlib import Path

import pytest

from fsi import config
from fsi.output import report_runs
from fsi.study import document as study_document
from fsi.study import findings as study_findings
from fsi.study import runs as study_runs

TIMES = [0.0025, 0.005, 0.01, 0.02, 0.05, 0.1, 0.8]


def run(
    name: str, sss: float, displacement: float = 1e-6, recirculation: float = 6e-3, end: float = 0.8
) -> report_runs.Run:
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
    return report_runs.Run(Path(name), config.Case(), rows, {"steps": len(rows)})


def summaries(runs: dict) -> dict:
    return {name: study_runs.summarise(r) for name, r in runs.items()}


def verdicts(runs: dict) -> list[str]:
    return [f.split(" — ")[1].split(" (")[0] for f in study_findings.findings(summaries(runs))]


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
    coarse = {f"{c}_coarse": run(f"{c}_coarse", 300.0) for c in study_runs.CONFIGS}
    fine = {f"{c}_fine": run(f"{c}_fine", 500.0) for c in study_runs.CONFIGS}
    assert "(fixed_newtonian_fine)" in study_findings.findings(summaries({**coarse, **fine}))[0]
    fine["fixed_carreau_fine"] = run("fixed_carreau_fine", 500.0, end=0.1)  # unfinished
    assert "(fixed_newtonian_coarse)" in study_findings.findings(summaries({**coarse, **fine}))[0]


def test_the_paper_tables_set_each_printed_value_beside_the_run_s(tmp_path):
    paper = study_runs.paper_values()
    assert len(paper) == 120  # 3 quantities x 5 times x 2 walls x 2 fluids x 2 meshes
    runs = {"fixed_newtonian_coarse": run("fixed_newtonian_coarse", 1.0, displacement=2e-6)}
    rows = study_runs.comparison_rows(summaries(runs), paper)
    key = ("displacement", 0.01, "fixed", "newtonian", "coarse")
    row = next(
        r for r in rows if (r["quantity"], r["t_s"], r["wall"], r["fluid"], r["mesh"]) == key
    )
    assert (row["paper"], row["fsi"]) == (paper[key], 2e-6)
    assert study_runs.difference(row) == pytest.approx(2e-6 / paper[key] - 1)
    assert sum(r["fsi"] is not None for r in rows) == 15  # this run's 3 quantities x 5 times
    table = study_document.paper_table(rows, "displacement", 1e6)
    line = next(x for x in table.splitlines() if x.startswith("| fixed wall, Newtonian | 0.01 |"))
    percent = f"{100 * (2e-6 / paper[key] - 1):+.0f} %"
    assert line.split(" | ")[2:5] == [f"{1e6 * paper[key]:.4g}", "2", percent]
    assert study_document.agreement(rows, "velocity").endswith("(35 without a run)")


def test_the_summaries_stand_in_for_the_run_folders(tmp_path):
    runs = {"fixed_newtonian_coarse": run("fixed_newtonian_coarse", 300.0, displacement=2e-6)}
    made = study_runs.make_summaries(runs, tmp_path, ["fixed_newtonian_coarse", "other"])
    read = study_runs.make_summaries({}, tmp_path, ["fixed_newtonian_coarse", "other"])
    assert read == json.loads(json.dumps(made)) and list(read) == ["fixed_newtonian_coarse"]
    assert study_runs.peak(read["fixed_newtonian_coarse"], "max_sss") == (300.0, 0.0025)
    assert study_runs.at(read["fixed_newtonian_coarse"], 0.05, "peak_displacement") == 2e-6


def test_the_committed_tables_hold_the_study_s_printed_values():
    """docs/study_tables.csv, as scripts/reproduce_study.py wrote it: the reference file's 120
    keys in its order, its values in the paper column, and an fsi value for each, read from the
    committed summary of its run (docs/study_runs/)."""
    root = Path(__file__).resolve().parents[1]
    with (root / "docs" / "study_tables.csv").open() as f:
        rows = list(csv.DictReader(f))
    paper = study_runs.paper_values()
    keys = [(r["quantity"], float(r["t_s"]), r["wall"], r["fluid"], r["mesh"]) for r in rows]
    assert keys == list(paper)
    assert [float(r["paper"]) for r in rows] == list(paper.values())
    assert all(r["fsi"] != "" and float(r["fsi"]) >= 0 for r in rows)
    # ... each the value of the committed run summary it was made from
    for r in rows:
        summary = json.loads(
            (
                root / "docs" / "study_runs" / f"{r['wall']}_{r['fluid']}_{r['mesh']}.json"
            ).read_text()
        )
        column = study_runs.PAPER_QUANTITY[r["quantity"]]
        assert r["fsi"] == f"{study_runs.at(summary, float(r['t_s']), column):.6g}", r


@pytest.mark.parametrize(
    "coarse,fine,expected", [(2.0, 3.0, "+50.0 %"), (2.0, None, "–"), (0.0, 1.0, "–")]
)
def test_change(coarse, fine, expected):
    assert study_runs.change(coarse, fine) == expected


def test_a_run_s_configuration_is_its_summary_s_or_its_command_s():
    """runs.run_case: the configuration a summary keeps; else its command's case file with the
    command's overrides (a sweep's run with its folder's), refused where that no longer gives
    the settings the summary recorded."""
    root = Path(__file__).resolve().parents[1]
    case = config.load(root / "configs" / "stenosis_fixed_newtonian.yaml", ["mesh.level=fine"])
    kept = {"name": "kept", "config": config.to_dict(case)}
    assert study_runs.run_case(kept) == case
    command = "fsi/__main__.py run configs/stenosis_fixed_newtonian.yaml --out results/x " + (
        "--set mesh.level=fine --set 'time.schedule=[{until: 0.8, dt: 0.01}]'"
    )
    record = json.loads(json.dumps(study_runs.case_record(case)))
    rebuilt = study_runs.run_case({"name": "x", "command": command, "case": record})
    assert rebuilt.mesh.level == "fine" and rebuilt.time.schedule[0].dt == 0.01
    sweep = "fsi/__main__.py sweep configs/stenosis_fixed_newtonian.yaml --out results/s " + (
        "--vary geometry.stenosis_degree=0.3,0.4 --set mesh.level=fine"
    )
    record["geometry"]["stenosis_degree"] = 0.3
    name = "geometry.stenosis_degree=0.3"
    swept = study_runs.run_case({"name": name, "command": sweep, "case": record})
    assert swept.geometry.stenosis_degree == 0.3
    record["geometry"]["stenosis_degree"] = 0.4  # not what the case file and overrides give
    with pytest.raises(ValueError, match="stenosis_degree"):
        study_runs.run_case({"name": name, "command": sweep, "case": record})
