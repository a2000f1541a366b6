"""The finished run folders ``fsi report`` (and the study, the sweeps' plots) read: a run's
``config.yaml``, ``metrics.csv`` and ``summary.json`` as one :class:`Run`
(:func:`load_run`, :func:`load_runs`), the checks of the report's arguments, and the choice of
a plot's scale (:func:`choose_scale`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from fsi import config
from fsi.output import metrics_csv


class ReportError(ValueError):
    """A run folder is missing a file or is not a run folder."""


def check_times(times: Sequence[float] | None) -> None:
    """Raise :class:`ReportError` naming ``--times`` unless every report time (s) is a finite
    number ≥ 0 given once (None: the runs' own report times)."""
    for i, t in enumerate(times or ()):
        if not math.isfinite(t) or t < 0:
            raise ReportError(f"--times {t}: expected a finite time >= 0 (s)")
        if t in times[:i]:
            raise ReportError(f"--times {t}: given twice")


@dataclass(frozen=True)
class Run:
    """A finished run folder: its resolved case, metrics rows (SI) and summary."""

    path: Path
    case: config.Case
    rows: list[dict[str, float]]
    summary: dict
    name: str = ""  # unique among the runs of a report (load_runs); default the folder's name

    @property
    def label(self) -> str:
        """The run's name in tables and legends: its name, mode, rheology and mesh level."""
        c = self.case
        return f"{self.title} ({c.structure.mode}, {c.fluid.rheology.model}, {c.mesh.level})"

    @property
    def title(self) -> str:
        """The run's name: :attr:`name`, or its folder's."""
        return self.name or self.path.name

    @property
    def stem(self) -> str:
        """The run's name as the start of a file name (``/`` → ``_``)."""
        return self.title.replace("/", "_")


def unique_names(paths: Sequence[Path]) -> list[str]:
    """A name for each run folder, unique among them unless two are the same folder: its
    folder name, with as many parent folders as it takes (``A/run`` and ``B/run``)."""
    resolved = [Path(p).resolve() for p in paths]
    distinct = set(resolved)
    names = []
    for path in resolved:
        for k in range(1, len(path.parts) + 1):
            tail = path.parts[-k:]
            if all(other.parts[-k:] != tail for other in distinct if other != path):
                break
        names.append("/".join(tail))
    return names


def load_runs(paths: Sequence[Path]) -> list[Run]:
    """:func:`load_run` of each path, named by :func:`unique_names`. Raises
    :class:`ReportError` for a run folder given twice (also as another spelling of the same
    folder, ``R`` and ``./R/``, or a link to it): its rows would be tabled twice."""
    seen: dict[Path, Path] = {}
    for path in paths:
        key = Path(path).resolve()
        if key in seen:
            same = "" if str(seen[key]) == str(path) else f" (as {seen[key]})"
            raise ReportError(f"RUN_DIR {path}: given twice{same}: each run is tabled once")
        seen[key] = Path(path)
    return [
        dataclasses.replace(load_run(path), name=name)
        for path, name in zip(paths, unique_names(paths), strict=True)
    ]


def check_out(out: Path | None) -> None:
    """Raises :class:`ReportError` unless ``out`` (None: no files) is a folder or a path where
    one can be made: not a file, nor below one."""
    if out is None:
        return
    existing = next(p for p in (out, *out.absolute().parents) if p.exists())
    if not existing.is_dir():
        what = "is a file" if existing == out else f"{existing} is a file"
        raise ReportError(f"--out {out}: {what}, not a folder")


def load_run(path: Path) -> Run:
    """A finished (or stopped, or running) run folder; summary.json is absent when the run
    stopped. The complete rows of metrics.csv (a last row cut short by a run stopped while
    writing it is left out, with a warning). Raises :class:`ReportError` naming the file (and
    the line of metrics.csv) if a file is missing, unreadable or damaged."""
    path = Path(path)
    for name in ("config.yaml", "metrics.csv"):
        if not (path / name).is_file():
            raise ReportError(f"{path}: no {name} (not a folder written by fsi run)")
    try:
        case = config.load(path / "config.yaml", run_config=True)
    except config.ConfigError as e:
        raise ReportError(f"{path}: {e}") from None
    try:
        rows = metrics_csv.read_metrics(path / "metrics.csv")
    except metrics_csv.MetricsError as e:
        raise ReportError(str(e)) from None
    except OSError as e:
        raise ReportError(f"{path / 'metrics.csv'}: unreadable ({e.strerror or e})") from None
    return Run(path, case, rows, _summary(path / "summary.json"))


def _summary(path: Path) -> dict:
    """summary.json's content; {} if there is none (a run that stopped)."""
    if not path.is_file():
        return {}
    try:
        summary = json.loads(path.read_bytes())
    except (OSError, ValueError) as e:
        raise ReportError(f"{path}: unreadable ({e})") from None
    if not isinstance(summary, dict):
        raise ReportError(f"{path}: not a summary written by fsi run")
    return summary


# --------------------------------------------------------------------------------------------
# Units and scales


MAGNITUDE_RATIO = 10.0
"""Groups of lines whose magnitudes (largest |value|) differ by more than this factor are not
drawn on one linear axis (:func:`choose_scale`)."""


def choose_scale(series: Sequence[Sequence[float]]) -> str:
    """How to draw groups of values on one plot (one sequence per group; empty ones are
    ignored): ``"linear"`` when their magnitudes (largest |value|) are within a factor
    :data:`MAGNITUDE_RATIO` of each other or there is at most one group; else ``"log"`` when
    every value is positive, ``"panels"`` (one panel per group) when one is not."""
    series = [list(values) for values in series if len(values)]
    peaks = [max(abs(v) for v in values) for values in series]
    if len(peaks) < 2 or max(peaks) <= MAGNITUDE_RATIO * min(peaks):
        return "linear"
    if all(v > 0 for values in series for v in values):
        return "log"
    return "panels"
