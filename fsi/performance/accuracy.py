"""The accuracy test of a speed setting (issue #46; docs/performance.md, "The accuracy test").

A faster scheme is judged against a **time-converged reference**: the fully implicit scheme
(Newton fluid, implicit geometry, no fluid forcing) with tight tolerances (coupling 1e-8, the
fluid's and the structure's Newton atol 1e-12) and every step of the case's schedule quartered,
compared at the case's own steps (:func:`reference_overrides`); a candidate with a schedule of
its own at the shipped steps it also took (:func:`at_shipped_times`). For every headline column
(:data:`fsi.performance.comparison.HEADLINE`) a run's **error** is the largest |x − x_ref| over
the compared times divided by the peak of |x_ref| over the run (:func:`errors`); the columns whose
exact value is ~0 (:data:`AGAINST_INLET`: the mean pressure at a stress-free outlet) are divided
by the peak of the inlet's mean pressure instead. The **shipped** run is the case as it is; a
**candidate** (a name and its overrides) **passes** where, in every column, its error is at most
max(1.25 × the shipped run's error, 0.5 %) (:func:`verdicts`).

Usage::

    .venv/bin/python scripts/accuracy_test.py configs/stenosis_moving_carreau.yaml \\
        --out results/accuracy [--ranks 2] [--set KEY=VALUE ...] [--reuse] \\
        [--candidate NAME KEY=VALUE[,KEY=VALUE ...] ...]

``--set`` applies to every run (e.g. ``time.end=0.05`` for a shorter window); without
``--candidate`` the candidates are :data:`CANDIDATES`. It prints a table of every run's errors
and verdicts and, as the last line of its standard output, one JSON object; it exits 1 if a
candidate fails.
"""

from __future__ import annotations

import argparse
import json
import subprocess
from collections.abc import Sequence
from pathlib import Path

from fsi import config
from fsi.numerics.timestepping import SAME_TIME
from fsi.output import metrics_csv
from fsi.performance.comparison import HEADLINE
from fsi.run import child_runs

CANDIDATES = {
    "extrapolated": ("fluid.solver.linearization=extrapolated",),
    "extrapolated_explicit": (
        "fluid.solver.linearization=extrapolated",
        "coupling.geometry=explicit",
    ),
}
"""The default candidates: the one-solve-per-step fluid, and with the frozen geometry."""

AGAINST_INLET = {"mean_outlet_pressure": "mean_inlet_pressure"}
"""Columns ~0 by the outlet condition → the column whose peak measures their error."""

TOLERANCE = {"coupling": 1e-8, "newton_atol": 1e-12}
"""The reference's tolerances (coupling residual; the fluid's and the structure's Newton atol)."""

STEP_FACTOR = 4
"""The reference's steps are the case's divided by this."""

RELATIVE_BOUND, ABSOLUTE_BOUND = 1.25, 5e-3
"""A candidate's error may be at most max(1.25 × the shipped run's, 0.5 %)."""


def reference_overrides(case: config.Case) -> list[str]:
    """The reference run's overrides of ``case``: the fully implicit scheme, tight tolerances,
    every segment of the schedule with its step divided by :data:`STEP_FACTOR`."""
    segments = ", ".join(
        f"{{until: {s.until!r}, dt: {s.dt / STEP_FACTOR!r}}}" for s in case.time.schedule
    )
    atol = TOLERANCE["newton_atol"]
    return [
        f"time.schedule=[{segments}]",
        f"coupling.tolerance={TOLERANCE['coupling']!r}",
        "coupling.geometry=implicit",
        "coupling.fluid_forcing=0.0",
        "fluid.solver.linearization=newton",
        f"fluid.solver.atol={atol!r}",
        "fluid.solver.rtol=1e-20",
        f"structure.solver.atol={atol!r}",
    ]


def at_times(rows: Sequence[dict], times: Sequence[float]) -> list[dict]:
    """The rows of ``rows`` at each of ``times`` (the same time to :data:`SAME_TIME`); raises
    ValueError naming the first time ``rows`` lacks."""
    found, i = [], 0
    for t in times:
        while i < len(rows) and rows[i]["t"] < t - SAME_TIME * max(abs(t), 1.0):
            i += 1
        if i == len(rows) or abs(rows[i]["t"] - t) > SAME_TIME * max(abs(t), 1.0):
            raise ValueError(f"the reference has no step at t = {t!r} s")
        found.append(rows[i])
    return found


def errors(rows: Sequence[dict], reference: Sequence[dict]) -> dict[str, float]:
    """Per headline column present in both: max over ``rows``' times of |x − x_ref| over the
    peak of |x_ref| over the whole reference (of the :data:`AGAINST_INLET` column for those)."""
    matched = at_times(reference, [r["t"] for r in rows])
    out = {}
    for column in HEADLINE:
        if column not in rows[0] or column not in reference[0]:
            continue
        scale_column = AGAINST_INLET.get(column, column)
        peak = max(abs(r[scale_column]) for r in reference)
        worst = max(abs(a[column] - b[column]) for a, b in zip(rows, matched))
        out[column] = worst / peak if peak > 0 else worst
    return out


def at_shipped_times(rows: Sequence[dict], shipped: Sequence[dict]) -> list[dict]:
    """The rows of ``rows`` at the shipped run's times: a candidate with its own schedule (finer
    in one stretch, coarser in another) is compared at the shipped steps it also took."""
    times = sorted(r["t"] for r in shipped)
    kept, i = [], 0
    for row in rows:
        t = row["t"]
        while i < len(times) and times[i] < t - SAME_TIME * max(abs(t), 1.0):
            i += 1
        if i < len(times) and abs(times[i] - t) <= SAME_TIME * max(abs(t), 1.0):
            kept.append(row)
    return kept


def verdicts(shipped: dict[str, float], candidate: dict[str, float]) -> dict[str, bool]:
    """Per column: the candidate's error at most max(1.25 × the shipped run's, 0.5 %)."""
    return {
        c: e <= max(RELATIVE_BOUND * shipped[c], ABSOLUTE_BOUND)
        for c, e in candidate.items()
        if c in shipped
    }


def table(
    results: dict[str, dict[str, float]],
    passed: dict[str, dict[str, bool]],
    unfinished: Sequence[str] = (),
) -> str:
    """Columns × runs, errors in %, a failing candidate's column marked; a candidate whose run
    failed (``unfinished``) has no errors and fails."""
    runs = [*results, *unfinished]
    lines = ["| column | " + " | ".join(runs) + " |", "|---" * (len(runs) + 1) + "|"]
    for column in results["shipped"]:
        cells = []
        for run in runs:
            if run in unfinished:
                cells.append("—")
                continue
            value = f"{100 * results[run][column]:.3f} %"
            if not passed.get(run, {}).get(column, True):
                value = f"**{value}**"
            cells.append(value)
        lines.append(f"| {column} | " + " | ".join(cells) + " |")
    verdict = ["—"] + [
        "**fails** (the run failed)"
        if r in unfinished
        else ("passes" if all(passed[r].values()) else "fails")
        for r in runs[1:]
    ]
    lines.append("| verdict | " + " | ".join(verdict) + " |")
    return "\n".join(lines)


def split_overrides(text: str) -> tuple[str, ...]:
    """``K=V,K=V`` split at the commas outside brackets and braces, so that a value may be a YAML
    list or mapping (``time.schedule=[{until: 0.05, dt: 5.0e-4}, ...]``)."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(text):
        depth += {"[": 1, "{": 1, "]": -1, "}": -1}.get(char, 0)
        if char == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return tuple(p.strip() for p in parts if p.strip())


def _candidates(pairs: Sequence[Sequence[str]] | None) -> dict[str, tuple[str, ...]]:
    if not pairs:
        return dict(CANDIDATES)
    return {name: split_overrides(overrides) for name, overrides in pairs}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("config", type=Path)
    parser.add_argument("--out", type=Path, required=True, help="folder of the runs")
    parser.add_argument("--ranks", type=int, default=1)
    parser.add_argument("--set", dest="settings", action="append", default=[], metavar="K=V")
    parser.add_argument("--candidate", nargs=2, action="append", metavar=("NAME", "K=V[,K=V...]"))
    parser.add_argument("--reuse", action="store_true", help="keep finished runs in --out")
    args = parser.parse_args(argv)
    case = config.load(args.config, list(args.settings))
    runs = {
        "reference": [*args.settings, *reference_overrides(case)],
        "shipped": list(args.settings),
        **{n: [*args.settings, *o] for n, o in _candidates(args.candidate).items()},
    }
    rows, unfinished = {}, []
    for name, overrides in runs.items():
        try:
            folder = child_runs.run(args.config, args.out / name, overrides, args.ranks, args.reuse)
        except subprocess.CalledProcessError:
            if name in ("reference", "shipped"):
                raise
            print(f"{name}: the run failed (its messages above): the candidate fails", flush=True)
            unfinished.append(name)
            continue
        rows[name] = metrics_csv.read_metrics(folder / "metrics.csv")
    reference = rows.pop("reference")
    results = {
        name: errors(at_shipped_times(r, rows["shipped"]), reference) for name, r in rows.items()
    }
    passed = {n: verdicts(results["shipped"], e) for n, e in results.items() if n != "shipped"}
    print(table(results, passed, unfinished))
    passed.update({name: {"finished": False} for name in unfinished})
    print(json.dumps({"errors": results, "passes": passed}))
    return 0 if all(all(p.values()) for p in passed.values()) else 1
