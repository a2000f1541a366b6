"""docs/study.md against the run summaries it was made from (docs/study_runs/): every value of
Tables 1–3 and its † (a maximum at a boundary's corner or an open boundary's edge), the places
and positions the document lists, where the element runs' peaks sit, the times of the
recirculation maxima, where the whole structure's SSS maximum sits, and the counts of values
within 10 % of the study's (the shipped and the most-plausible configuration). Each check is a
function that returns its mismatches, so a document edited by hand (or made from other
summaries) fails; the last test shows that it does."""

import json
import re
from pathlib import Path

import pytest

from fsi.study import locations, plausible
from fsi.study import runs as study_runs

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
LABEL_CONFIG = {label: c for c, label in study_runs.LABELS.items()}


def load_summaries(folder: Path) -> dict[str, dict]:
    """Every summary under ``folder`` by its name relative to it (``element/p1p1_coarse``)."""
    return {
        str(p.relative_to(folder).with_suffix("")): json.loads(p.read_text())
        for p in folder.rglob("*.json")
        if p.name != "static_compliance.json"
    }


def table_mismatches(doc: str, summaries: dict) -> list[str]:
    """Tables 1–3: each fsi value as the summary's, marked † exactly where its maximum sits at
    a boundary's corner or an open boundary's edge."""
    bad = []
    for column, title, _, scale in study_runs.QUANTITIES:
        section = doc.split(f"### {title}")[1].split("\n\n", 2)[1]
        rows = [r for r in section.splitlines() if r.startswith("| ") and " wall, " in r]
        assert len(rows) == 20, title
        for row in rows:
            cells = [c.strip() for c in row.strip("|").split("|")]
            config, t = LABEL_CONFIG[cells[0]], float(cells[1])
            for mesh, cell in (("coarse", cells[3]), ("fine", cells[6])):
                s = summaries.get(f"{config}_{mesh}")
                value = study_runs.at(s, t, column)
                place = (study_runs.where(s, t, column) or {}).get("place")
                expected = study_runs.fmt(None if value is None else scale * value)
                expected += " †" if place else ""
                if cell != expected:
                    bad.append(
                        f"{title}, {config}_{mesh} at {t:g} s: {cell!r}, summary {expected!r}"
                    )
    return bad


PLACED = re.compile(r"(\w+) at ([\d.]+) s: ([^;(]+?) \(x = (-?[\d.]+) mm, y = (-?[\d.]+) mm\)")


def place_mismatches(doc: str, summaries: dict) -> list[str]:
    """The † lists: each run, time, place and position as the run's summary keeps them."""
    bad, found = [], 0
    for block in re.findall(r"† The maximum sits at .*", doc):
        title = doc[: doc.index(block)].rsplit("### ", 1)[1].split("\n")[0].split(" (")[0]
        column = next(c for c, t, *_ in study_runs.QUANTITIES if t == title)
        for run, t, place, x, y in PLACED.findall(block):
            found += 1
            w = study_runs.where(summaries.get(run), float(t), column) or {}
            got = (place, x, y)
            want = (
                locations.describe(w.get("place")),
                locations.mm(w.get("x", 0)),
                locations.mm(w.get("y", 0)),
            )
            if got != want:
                bad.append(f"{title}: {run} at {t} s: {got}, summary {want}")
    return bad


ELEMENT_ROW = re.compile(
    r"^\| fsi (P\d–P1)[^,]*, (coarse|fine) \|.*\| \((-?[\d.]+), (-?[\d.]+)\)( † [^|]+)?"
    r" \| [\d.]+ \|$",
    re.M,
)


def element_mismatches(doc: str, summaries: dict) -> list[str]:
    """The element table: where each run's 10 ms peak pressure sits, and its †."""
    bad, rows = [], ELEMENT_ROW.findall(doc)
    if len(rows) != 4:
        return [f"the element table has {len(rows)} located rows, not 4"]
    for element, mesh, x, y, mark in rows:
        s = summaries.get(f"element/{element.lower().replace('–', '')}_{mesh}")
        w = study_runs.where(s, 0.01, "peak_pressure") or {}
        want = (locations.mm(w.get("x", 0)), locations.mm(w.get("y", 0)))
        place = locations.describe(w.get("place"))
        if (x, y) != want or mark.strip(" †") != place:
            bad.append(f"element {element} {mesh}: ({x}, {y}){mark}, summary {want} {place}")
    return bad


def findings_mismatches(doc: str, summaries: dict) -> list[str]:
    """The recirculation maxima's times, and where the whole structure's SSS maximum sits."""
    bad = []
    fine = [summaries.get(f"{c}_fine") for c in study_runs.CONFIGS]
    level = "fine" if all(map(study_runs.finished, fine)) else "coarse"  # as the findings pick
    m = re.search(r"\(Newtonian / Carreau, at t = ([\d.]+) / ([\d.]+) s\), moving [^(]*"
                  r"\(at t = ([\d.]+) / ([\d.]+) s\)", doc)  # fmt: skip
    if m is None:
        return ["the recirculation finding states no times"]
    want = [
        f"{study_runs.peak(summaries[f'{c}_{level}'], 'recirculation_length')[1]:.3g}"
        for c in study_runs.CONFIGS
    ]
    if list(m.groups()) != want:
        bad.append(f"recirculation times {m.groups()}, summaries {want}")
    cell = summaries[f"moving_newtonian_{level}"].get("largest_sss_at")
    m = re.search(r"moving wall's largest SSS \(([\d.e+]+) Pa at t = ([\d.]+) s, (\w+)\) is[^.]*?"
                  r"x = (-?[\d.]+) mm, y = (-?[\d.]+) mm", doc)  # fmt: skip
    if cell is None or m is None:
        return bad + ["the clamped-corner note or its summary is missing"]
    if m.group(4, 5) != (locations.mm(cell["x"]), locations.mm(cell["y"])):
        bad.append(f"the SSS maximum at {m.group(4, 5)}, summary ({cell['x']}, {cell['y']})")
    return bad


def count_mismatches(doc: str, summaries: dict) -> list[str]:
    """The count of values within 10 % of the study's, over all 120 and per configuration."""
    paper = study_runs.paper_values()
    rows = study_runs.comparison_rows(summaries, paper)
    close = sum(abs(d) <= 0.1 for d in map(study_runs.difference, rows) if d is not None)
    bad = []
    if f"fsi is within 10 % of the paper for {close} of 120 values" not in doc:
        bad.append(f"the 120-value count is not {close}")
    extra = {"plausible": {n: s for n, s in summaries.items() if n.startswith("plausible/")}}
    table = plausible.count_table(
        summaries, {n.split("/")[1]: s for n, s in extra["plausible"].items()}, paper
    )
    if table not in doc:
        bad.append("the shipped / most-plausible count table is not the summaries'")
    return bad


CHECKS = (table_mismatches, place_mismatches, element_mismatches, findings_mismatches,
          count_mismatches)  # fmt: skip


@pytest.mark.parametrize("check", CHECKS, ids=lambda c: c.__name__)
def test_the_document_states_what_the_summaries_hold(check):
    doc = (DOCS / "study.md").read_text()
    assert check(doc, load_summaries(DOCS / "study_runs")) == []


def test_a_document_edited_by_hand_fails_each_check():
    """One fact changed in a copy of the document is found by the check that covers it."""
    doc = (DOCS / "study.md").read_text()
    summaries = load_summaries(DOCS / "study_runs")
    element = ELEMENT_ROW.search(doc).group(0)
    row = next(r for r in doc.splitlines() if r.startswith("| fixed wall, Newtonian | 0.01 |"))
    cells = row.split(" | ")
    cells[3] += "1"  # fsi's coarse value, one digit more
    edits = {
        table_mismatches: (row, " | ".join(cells)),
        element_mismatches: (element, "(1".join(element.rsplit("(", 1))),
        findings_mismatches: ("(Newtonian / Carreau, at t = ", "(Newtonian / Carreau, at t = 9"),
        count_mismatches: ("of the paper for ", "of the paper for 1"),
    }
    for check, (old, new) in edits.items():
        assert old in doc, check.__name__
        assert check(doc.replace(old, new, 1), summaries) != [], check.__name__
    placed = PLACED.search(doc)
    if placed is not None:
        assert place_mismatches(doc.replace(placed.group(0), placed.group(0).replace(
            "x = ", "x = 1", 1)), summaries) != []  # fmt: skip
