"""The steppers' side of adaptive time stepping (``time.step_control: adaptive``): the local
time error of each step, measured on the fields that control the step size
(:class:`TimeErrors`, built for a case by :func:`build`). The choice of the steps is
fsi.numerics.timestepping's (:class:`~fsi.numerics.timestepping.AdaptiveSteps`, driven by
fsi/run/simulation.py).
"""

from __future__ import annotations

from mpi4py import MPI

import numpy as np

from fsi import config
from fsi.numerics.timestepping import LocalError
from fsi.run.state_arrays import Layout

COLUMN = "time_error"
"""The metrics column of a step's error estimate (empty while there is none)."""


class TimeErrors:
    """The :class:`~fsi.numerics.timestepping.LocalError` of each controlled field (the fluid's
    velocity, the structure's displacement): ``fields`` maps a name to the Function and the
    checkpoint layout of its values, ``floors`` the size each is expected to reach (the
    LocalError's floor). :meth:`after_step` estimates a step's error (the largest
    over the fields) and records the step's values as accepted: a step the run rejects is
    undone with the stepper's state (:meth:`state`, :meth:`load_state`).

    The fields' values at ``t0`` (the run's start) are the first recorded level. With no
    ``fields`` (steps as scheduled) it adds no column, row entry or state."""

    def __init__(
        self,
        comm,
        fields: dict[str, tuple[object, Layout]],
        t0: float,
        floors: dict[str, float] | None = None,
    ):
        self.fields = fields
        self.errors = {
            name: LocalError(comm, layout.owned * layout.block, (floors or {}).get(name, 0.0))
            for name, (_, layout) in fields.items()
        }
        self._accept(t0)

    @property
    def columns(self) -> list[str]:
        """The metrics column :data:`COLUMN`, or none without controlled fields."""
        return [COLUMN] if self.fields else []

    def _accept(self, t: float) -> None:
        for name, (function, _) in self.fields.items():
            self.errors[name].accept(function.x.array, t)

    def after_step(self, t: float) -> dict:
        """The step to ``t`` just taken: its row's :data:`COLUMN` (the largest estimate, or ''
        while there is none); its values are recorded. Collective."""
        if not self.fields:
            return {}
        estimates = [
            self.errors[name].estimate(function.x.array, t)
            for name, (function, _) in self.fields.items()
        ]
        self._accept(t)
        known = [e for e in estimates if e is not None]
        return {COLUMN: max(known) if known else ""}

    def layouts(self) -> dict[str, Layout]:
        """The checkpoint layout of each field's recorded levels (:meth:`state`)."""
        return {f"time_error.{name}.values": layout for name, (_, layout) in self.fields.items()}

    def state(self) -> dict[str, np.ndarray]:
        """``time_error.<field>.values``, ``.times``, ``.scale`` (LocalError.state)."""
        return {
            f"time_error.{name}.{key}": value
            for name, error in self.errors.items()
            for key, value in error.state().items()
        }

    def load_state(self, state: dict[str, np.ndarray], t: float) -> None:
        """Take back :meth:`state`; from a checkpoint without it (written by a run with fixed
        steps) the fields' current values at ``t`` are the first level."""
        for name, error in self.errors.items():
            prefix = f"time_error.{name}."
            if prefix + "values" in state:
                error.load_state({k: state[prefix + k] for k in ("values", "times", "scale")})
            else:
                error.load_state(
                    {"values": np.zeros((0, 0)), "times": np.zeros(0), "scale": np.array(0.0)}
                )
                error.accept(self.fields[name][0].x.array, t)


FIELD_LAYOUTS = {"fluid": "fluid.u_n", "structure": "solid.eta"}
"""The checkpoint layout of each controlled field's values (those of its history's)."""


def build(case: config.Case, comm: MPI.Comm, fields: dict) -> TimeErrors:
    """The :class:`TimeErrors` of a stepper.

    Args:
        case: the run's case; with ``time.step_control: adaptive`` the fields are controlled,
            their floors ``time.adaptive.velocity_scale`` (m/s) and ``displacement_scale`` (m).
        comm: the run's communicator.
        fields: ``fluid`` and/or ``structure`` → (the Function, the stepper's layouts).

    Returns:
        The TimeErrors of ``fields`` (their values at t = 0 the first level) when adaptive, else
        of none.
    """
    adaptive = case.time.step_control == "adaptive"
    settings = case.time.adaptive
    return TimeErrors(
        comm,
        {
            name: (f, layouts[FIELD_LAYOUTS[name]])
            for name, (f, layouts) in fields.items()
            if adaptive
        },
        0.0,
        {"fluid": settings.velocity_scale, "structure": settings.displacement_scale},
    )
