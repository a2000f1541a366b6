"""How far one run's answer is from another's: the largest difference of each headline column of
``metrics.csv`` over the steps, relative to the reference run's peak of that column (the measure
of the speed settings against a tight solve: docs/performance.md, tests/test_solver_settings.py).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

HEADLINE = (
    "peak_velocity",
    "peak_pressure",
    "peak_displacement",
    "max_sss",
    "max_principal_cap",
    "min_wss",
    "max_wss",
    "inlet_flow_rate",
    "outlet_flow_rate",
    "mean_inlet_pressure",
    "mean_outlet_pressure",
)
"""The columns a study run is judged by (those of a rigid-wall run are a subset)."""


def largest_differences(
    rows: Sequence[dict], reference: Sequence[dict], columns: Iterable[str] = HEADLINE
) -> dict[str, float]:
    """Per column present in both runs, max over the steps of |rows − reference| divided by
    max |reference|. The runs must have the same steps (same number of rows, same times)."""
    if len(rows) != len(reference):
        raise ValueError(f"{len(rows)} rows against a reference of {len(reference)}")
    for a, b in zip(rows, reference):
        if abs(a["t"] - b["t"]) > 1e-9 * max(abs(b["t"]), 1.0):
            raise ValueError(f"the runs' steps differ: t = {a['t']} against {b['t']}")
    out = {}
    for column in columns:
        if column not in reference[0] or column not in rows[0]:
            continue
        peak = max(abs(r[column]) for r in reference)
        worst = max(abs(a[column] - b[column]) for a, b in zip(rows, reference))
        out[column] = worst / peak if peak > 0 else worst
    return out
