"""The ``output`` section (:class:`Output`): what a run writes and how often."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from fsi.config.reader import at_least, checked


@dataclass(frozen=True)
class Output:
    """``fields``: the format of the field files; ``fields_every`` and ``checkpoint_every``:
    write the fields and a checkpoint every this many steps; ``report_times``: the times (s)
    the report tabulates (an adaptive run steps onto each)."""

    # XDMF only: Debian 12's dolfinx has no ADIOS2 (no VTX), and 0.9's VTX writer takes one
    # element per file, where a run writes P1 and per-cell fields side by side.
    fields: Literal["xdmf"] = "xdmf"
    fields_every: int = at_least(1, 1)
    checkpoint_every: int = at_least(10, 1)
    report_times: tuple[float, ...] = checked(
        (0.01, 0.02, 0.05, 0.1, 0.8), lambda v: all(t >= 0 for t in v), "a list of times >= 0 (s)"
    )
