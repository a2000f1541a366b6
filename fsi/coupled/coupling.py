"""Dirichlet–Neumann coupling: interface accelerations as pure objects, and the per-step loop.

A step's coupled problem is the fixed point ``x = H(x)`` of the interface displacement ``x``:
the fluid takes ``x`` and returns the interface traction, the solid takes that traction and
returns ``x̃ = H(x)``. :func:`couple_step` iterates from a :class:`Predictor` with an
:class:`Acceleration` (:class:`ConstantRelaxation`, :class:`Aitken`, :class:`IQNILS`) against
two :class:`InterfaceSolver`. Inner products are MPI-global, so the iterates do not depend on
the number of ranks.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from mpi4py import MPI

import numpy as np

from fsi.numerics.timestepping import extrapolation_weights

if TYPE_CHECKING:
    from fsi.config import Coupling

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------------------------
# MPI-global linear algebra on distributed interface vectors


def dot(comm: MPI.Comm, a: np.ndarray, b: np.ndarray) -> float:
    """The global inner product a·b of two distributed vectors (each rank holds its slice)."""
    return float(comm.allreduce(float(np.dot(a, b)), op=MPI.SUM))


def norm(comm: MPI.Comm, a: np.ndarray) -> float:
    """The global Euclidean norm |a| of a distributed vector."""
    return float(np.sqrt(dot(comm, a, a)))


def relative_residual(comm: MPI.Comm, x: np.ndarray, x_tilde: np.ndarray) -> float:
    """``|x̃ − x| / |x̃|``, the coupling criterion (``|x̃ − x|`` when ``x̃ = 0``)."""
    scale = norm(comm, x_tilde)
    difference = norm(comm, x_tilde - x)
    return difference / scale if scale > 0 else difference


def filtered_qr(comm: MPI.Comm, columns: Sequence[np.ndarray], threshold: float):
    """QR decomposition ``V = Q R`` of distributed columns, dropping dependent ones.

    Columns are taken in the given order (put the most valuable first) and orthogonalised by
    classical Gram–Schmidt with reorthogonalisation ("twice is enough"), one global reduction
    per pass. Column ``v_i`` is dropped when what is left of it after orthogonalisation is
    ``|v_i − Q Qᵀ v_i| < threshold · |v_i|`` (the relative "QR2" filter of Haelterman et al.
    2016), so a (nearly) repeated or zero column never makes ``R`` singular.

    Returns ``(Q, R, kept)``: ``Q`` (local rows × m) with orthonormal columns, ``R`` (m × m)
    upper triangular, ``kept`` the indices of the m kept columns.
    """
    n_local = columns[0].shape[0] if len(columns) else 0
    q_columns: list[np.ndarray] = []
    r_columns: list[np.ndarray] = []
    kept: list[int] = []
    for i, v in enumerate(columns):
        size = norm(comm, v)
        m = len(q_columns)
        coefficients = np.zeros(m)
        w = np.array(v, dtype=float)
        if m:
            Q = np.column_stack(q_columns)
            for _ in range(2):
                c = comm.allreduce(Q.T @ w, op=MPI.SUM)
                w -= Q @ c
                coefficients += c
        remainder = norm(comm, w)
        if size == 0.0 or remainder < threshold * size:
            continue
        q_columns.append(w / remainder)
        r_columns.append(np.append(coefficients, remainder))
        kept.append(i)
    m = len(q_columns)
    Q = np.column_stack(q_columns) if m else np.zeros((n_local, 0))
    R = np.zeros((m, m))
    for j, r in enumerate(r_columns):
        R[: j + 1, j] = r
    return Q, R, kept


# --------------------------------------------------------------------------------------------
# Accelerations


class Acceleration(Protocol):
    """Chooses the next interface input of a step's fixed-point iterations."""

    def start_step(self, weights: np.ndarray | None = None) -> None:
        """A new time step begins (its first ``next_input`` follows); its secants and least
        squares measure the entries of the inputs times ``weights`` (local; None: as they are)."""

    def next_input(self, x: np.ndarray, x_tilde: np.ndarray) -> np.ndarray:
        """The next input ``x_{k+1}`` from the input ``x_k`` and the output ``x̃_k = H(x_k)``."""

    def end_step(self) -> None:
        """The step converged: keep what the next step reuses."""

    def state(self) -> dict[str, np.ndarray]:
        """What a later step reuses (between steps), as named local arrays for a checkpoint."""

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Take back :meth:`state` (keys of another acceleration are ignored)."""

    @property
    def relaxation(self) -> float | None:
        """The relaxation factor ω of the last iteration, or None (quasi-Newton)."""


class ConstantRelaxation:
    """``x_{k+1} = x_k + ω (x̃_k − x_k)``, the same ω in every iteration."""

    def __init__(self, comm: MPI.Comm, omega: float):
        if not 0 < omega:
            raise ValueError(f"relaxation factor must be positive, got {omega}")
        self.comm, self.omega = comm, omega

    def start_step(self, weights: np.ndarray | None = None) -> None:
        pass  # measures nothing

    def next_input(self, x: np.ndarray, x_tilde: np.ndarray) -> np.ndarray:
        return x + self.omega * (x_tilde - x)

    def end_step(self) -> None:
        pass

    def state(self) -> dict[str, np.ndarray]:
        return {}  # ω is the configuration's

    @property
    def relaxation(self) -> float:
        return float(self.omega)

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        pass


class Aitken:
    """Aitken's Δ² dynamic relaxation (Küttler & Wall 2008, Comput. Mech. 43:61–72).

    ``x_{k+1} = x_k + ω_k r_k`` with ``r_k = x̃_k − x_k`` and, from the second iteration of a
    step on, ``ω_k = −ω_{k−1} r_{k−1}·(r_k − r_{k−1}) / |r_k − r_{k−1}|²`` (global dot products
    of the residuals times the step's weights, :meth:`start_step`), the secant of the residual
    along the last step. ``|ω| <= omega_max`` always. The first step
    starts with ``omega_initial``; every later step starts with the last ω of the step before.
    For a scalar (or ``a I``) linear map the second ω is exact: three evaluations converge.
    """

    def __init__(
        self,
        comm: MPI.Comm,
        omega_initial: float,
        omega_max: float = 1.0,
    ):
        if not 0 < omega_initial <= omega_max:
            raise ValueError(
                f"need 0 < omega_initial <= omega_max, got {omega_initial}, {omega_max}"
            )
        self.comm, self.omega_max, self.weights = comm, omega_max, None
        self.omega = omega_initial
        self._previous_residual: np.ndarray | None = None

    @property
    def relaxation(self) -> float:
        return float(self.omega)

    def _capped(self, omega: float) -> float:
        return float(np.sign(omega) * min(abs(omega), self.omega_max))

    def start_step(self, weights: np.ndarray | None = None) -> None:
        self.weights = weights
        self._previous_residual = None
        self.omega = self._capped(self.omega)

    def next_input(self, x: np.ndarray, x_tilde: np.ndarray) -> np.ndarray:
        r = x_tilde - x
        if self._previous_residual is not None:
            dr = _weighted(self.weights, r - self._previous_residual)
            dr2 = dot(self.comm, dr, dr)
            if dr2 > 0.0:  # an unchanged residual leaves ω as it is
                previous = _weighted(self.weights, self._previous_residual)
                secant = dot(self.comm, previous, dr) / dr2
                self.omega = self._capped(-self.omega * secant)
        self._previous_residual = r
        return x + self.omega * r

    def end_step(self) -> None:
        self._previous_residual = None

    def state(self) -> dict[str, np.ndarray]:
        """The ω carried into the next step (``aitken.omega``)."""
        return {"aitken.omega": np.array(self.omega)}

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        if "aitken.omega" in state:  # else (another acceleration's state): omega_initial
            self.omega = float(state["aitken.omega"])
        self._previous_residual = None


class IQNILS:
    """Interface quasi-Newton, inverse Jacobian from a least-squares model (IQN-ILS).

    Degroote, Bathe & Vierendeels 2009 (Comput. Struct. 87:793–801). With ``r_k = x̃_k − x_k``,
    the columns ``V = [Δr]`` and ``W = [Δx̃]`` hold the differences of successive residuals and
    outputs, this step's newest first, then those of the last ``reuse`` converged steps. The update

        x_{k+1} = x̃_k + W c,   c = argmin_c |V c + r_k|,

    takes ``c`` from :func:`filtered_qr` (``R c = −Qᵀ r_k``), which drops the columns that are
    (nearly) dependent on newer ones. Without any column (the first iteration of the first step,
    or of every step with ``reuse = 0``) it is the relaxation ``x_{k+1} = x_k + ω r_k``. On a
    linear map of dimension n the columns span GMRES's Krylov space: at most n + 1 updates reach
    the fixed point. The step's ``weights`` (:meth:`start_step`) scale the entries the least
    squares measure; the update moves every entry with the same coefficients c.
    """

    def __init__(
        self,
        comm: MPI.Comm,
        omega: float,
        reuse: int = 0,
        threshold: float = 1e-8,
    ):
        if omega <= 0 or reuse < 0 or threshold <= 0:
            raise ValueError(
                f"need omega > 0, reuse >= 0, threshold > 0; got {omega}, {reuse}, {threshold}"
            )
        self.comm, self.omega, self.threshold, self.weights = comm, omega, threshold, None
        self._old_steps: deque[tuple[list[np.ndarray], list[np.ndarray]]] = deque(maxlen=reuse or 1)
        self.reuse = reuse
        self._V: list[np.ndarray] = []  # this step's Δr, newest first
        self._W: list[np.ndarray] = []  # this step's Δx̃, newest first
        self._previous: tuple[np.ndarray, np.ndarray] | None = None  # (r_{k−1}, x̃_{k−1})
        self.columns_used = 0  # after next_input: columns kept by the filter
        self.columns_dropped = 0  # after next_input: columns removed by the filter

    @property
    def relaxation(self) -> None:
        return None  # a least-squares update, no single ω

    def start_step(self, weights: np.ndarray | None = None) -> None:
        self.weights = weights
        self._V, self._W, self._previous = [], [], None

    def next_input(self, x: np.ndarray, x_tilde: np.ndarray) -> np.ndarray:
        r = x_tilde - x
        if self._previous is not None:
            r_old, x_tilde_old = self._previous
            self._V.insert(0, r - r_old)
            self._W.insert(0, x_tilde - x_tilde_old)
        self._previous = (r.copy(), np.array(x_tilde, dtype=float))
        V, W = list(self._V), list(self._W)
        if self.reuse:
            for V_old, W_old in reversed(self._old_steps):
                V.extend(V_old)
                W.extend(W_old)
        V = [_weighted(self.weights, v) for v in V]
        Q, R, kept = filtered_qr(self.comm, V, self.threshold) if V else (None, None, [])
        self.columns_used, self.columns_dropped = len(kept), len(V) - len(kept)
        if not kept:
            return x + self.omega * r
        measured = _weighted(self.weights, r)
        c = np.linalg.solve(R, -self.comm.allreduce(Q.T @ measured, op=MPI.SUM))
        return x_tilde + np.column_stack([W[i] for i in kept]) @ c

    def end_step(self) -> None:
        if self.reuse and self._V:
            self._old_steps.append((self._V, self._W))
        self._V, self._W, self._previous = [], [], None

    def state(self) -> dict[str, np.ndarray]:
        """The columns kept from past steps: ``iqn.V.i``/``iqn.W.i`` (local rows × columns,
        newest column first) of the i-th kept step, oldest step first; ``iqn.steps`` their
        number. The current step's columns are not part of it (it is taken between steps)."""
        arrays = {"iqn.steps": np.array(len(self._old_steps))}
        for i, (V, W) in enumerate(self._old_steps):
            arrays[f"iqn.V.{i}"], arrays[f"iqn.W.{i}"] = np.column_stack(V), np.column_stack(W)
        return arrays

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Past steps' columns (the newest ``reuse`` of them); none from another acceleration."""
        self._old_steps.clear()
        for i in range(int(state.get("iqn.steps", 0))):
            V, W = state[f"iqn.V.{i}"], state[f"iqn.W.{i}"]
            self._old_steps.append(([c.copy() for c in V.T], [c.copy() for c in W.T]))
        self._V, self._W, self._previous = [], [], None


def _weighted(weights: np.ndarray | None, v: np.ndarray) -> np.ndarray:
    return v if weights is None else weights * v


ACCELERATIONS: dict[str, Callable[..., Acceleration]] = {
    "constant": lambda c, comm: ConstantRelaxation(comm, c.initial_relaxation),
    "aitken": lambda c, comm: Aitken(comm, c.initial_relaxation, c.max_relaxation),
    "iqn-ils": lambda c, comm: IQNILS(comm, c.initial_relaxation, c.iqn_reuse, c.iqn_filter),
}
"""The accelerations by the ``coupling.acceleration`` tag, built from the coupling section."""


def from_config(coupling: Coupling, comm: MPI.Comm) -> Acceleration:
    """The acceleration named by ``coupling.acceleration`` with the configuration's parameters."""
    return ACCELERATIONS[coupling.acceleration](coupling, comm)


# --------------------------------------------------------------------------------------------
# Predictor


PREDICTOR_ORDERS = {"constant": 0, "linear": 1, "quadratic": 2, "cubic": 3}


class Predictor:
    """The first interface input of a step, extrapolated from the converged interface values of
    the previous steps by the polynomial of degree ``order`` through the last ``order + 1`` of
    them (fewer while fewer are known):

        constant  x_{n+1} = x_n
        linear    x_{n+1} = x_n + (t_{n+1} − t_n)/(t_n − t_{n−1}) (x_n − x_{n−1})
                  (= 2 x_n − x_{n−1} for equal steps)
        quadratic the Lagrange polynomial through (t_{n−2}, x_{n−2}), …, (t_n, x_n)
                  (= 3 x_n − 3 x_{n−1} + x_{n−2} for equal steps)
        cubic     the Lagrange polynomial through the last four
                  (= 4 x_n − 6 x_{n−1} + 4 x_{n−2} − x_{n−3} for equal steps)

    Record the initial value first (``record(x_0, t_0)``). Times are optional: if any is
    missing, the steps are taken as equal.
    """

    def __init__(self, order: int | str = 1):
        self.order = PREDICTOR_ORDERS[order] if isinstance(order, str) else int(order)
        if self.order not in PREDICTOR_ORDERS.values():
            raise ValueError(f"predictor order must be 0, 1, 2 or 3, got {order!r}")
        self._values: deque[np.ndarray] = deque(maxlen=self.order + 1)
        self._times: deque[float] = deque(maxlen=self.order + 1)

    def record(self, x: np.ndarray, t: float | None = None) -> None:
        """Remember the converged interface value at time ``t`` (the end of a step)."""
        self._values.append(np.array(x, dtype=float))
        self._times.append(np.nan if t is None else float(t))

    def predict(self, t: float | None = None) -> np.ndarray:
        """The extrapolated value at time ``t`` (one more equal step when ``t`` is not given)."""
        if not self._values:
            raise ValueError("Predictor.predict: record the initial interface value first")
        values, times = list(self._values), np.array(self._times)
        m = len(values)
        if t is None or np.isnan(times).any():
            times, t = np.arange(m, dtype=float), float(m)
        return sum(w * v for w, v in zip(extrapolation_weights(times, t), values))

    def state(self) -> dict[str, np.ndarray]:
        """The recorded values (``values``: local interface entries × recorded steps, oldest
        first) and their times (``times``; empty if any was not given)."""
        times = np.array(self._times, dtype=float)
        return {
            "values": (np.column_stack(list(self._values)) if self._values else np.zeros((0, 0))),
            "times": times if not np.isnan(times).any() else np.zeros(0),
        }

    def load_state(self, state: dict[str, np.ndarray]) -> None:
        """Take back :meth:`state`; of more values than this order needs, the newest count."""
        values, times = state["values"].T, state["times"]
        self._values.clear()
        self._times.clear()
        for i, x in enumerate(values):
            self.record(x, float(times[i]) if len(times) == len(values) else None)


def predictor_from_config(coupling: Coupling) -> Predictor:
    """The predictor named by ``coupling.predictor`` (constant, linear, quadratic or cubic)."""
    return Predictor(coupling.predictor)


# --------------------------------------------------------------------------------------------
# The unknown of a step's iterations


@dataclass(frozen=True)
class InterfaceUnknown:
    """What a step's iterations solve for, per owned interface node: the displacement x
    (``dimension`` values; Dirichlet–Neumann) or, with ``forces``, x followed by the fluid's
    nodal forces f (Robin–Neumann: the fluid's Robin data are the last iterate's forces, so they
    are part of the fixed point z = [x, f]). The predictor extrapolates both. The accelerations
    and the step's convergence measure z in metres (:meth:`weights`): x as it is, f times
    c = Δt / (α Ā), which turns a change of the Robin data into the slip it leaves, u − u_Γ,
    over one step (α the Robin coefficient, Ā the interface's area per node;
    :meth:`fsi.coupled.adapters.FluidInterface.weights`)."""

    dimension: int
    forces: bool = False

    @property
    def block(self) -> int:
        """Values per node."""
        return 2 * self.dimension if self.forces else self.dimension

    def stack(self, x: np.ndarray, f: np.ndarray | None = None) -> np.ndarray:
        """z from x and (with ``forces``) f, both flat or (n, dimension); f None: zero."""
        if not self.forces:
            return np.asarray(x, dtype=float).ravel()
        x = np.asarray(x, dtype=float).reshape(-1, self.dimension)
        f = np.zeros_like(x) if f is None else np.asarray(f, dtype=float).reshape(x.shape)
        return np.hstack([x, f]).ravel()

    def displacement(self, z: np.ndarray) -> np.ndarray:
        """x of z (flat)."""
        return np.asarray(z).reshape(-1, self.block)[:, : self.dimension].ravel()

    def nodal_forces(self, z: np.ndarray) -> np.ndarray:
        """f of z (flat; with ``forces`` only)."""
        return np.asarray(z).reshape(-1, self.block)[:, self.dimension :].ravel()

    def weights(self, size: int, force_weight: float) -> np.ndarray | None:
        """1 on the displacement's entries of a local z of ``size`` values, ``force_weight`` (m/N)
        on the forces' (None without forces: every entry counts as it is)."""
        if not self.forces:
            return None
        w = np.full((size // self.block, self.block), float(force_weight))
        w[:, : self.dimension] = 1.0
        return w.ravel()


# --------------------------------------------------------------------------------------------
# The Dirichlet–Neumann loop


class InterfaceSolver(Protocol):
    """What the coupler needs from the fluid and the solid solver of a partitioned step.

    The fluid's ``solve`` takes the interface displacement and returns the interface traction;
    the solid's takes the traction and returns the displacement (local slices of distributed
    vectors in both directions).
    """

    def save_state(self) -> None:
        """Checkpoint the state at the start of the step (the previous step's solution)."""

    def restore_state(self) -> None:
        """Go back to the checkpoint before solving the step again with a new input."""

    def solve(self, interface_input: np.ndarray) -> np.ndarray:
        """Solve the step for the given interface input; return the interface output."""

    def advance(self) -> None:
        """Accept the last solve as the step's solution and move to the next step."""


class CouplingNotConverged(RuntimeError):
    """The interface residual stayed above the tolerance for ``max_iterations`` iterations.

    ``step``: the step's number; ``residuals``: the relative residual of every iteration. Both
    solvers have been restored to the start of the step (their last converged state).
    """

    def __init__(self, step: int, residuals: Sequence[float], tolerance: float):
        self.step, self.residuals, self.tolerance = step, list(residuals), tolerance
        super().__init__(
            f"coupling did not converge in step {step}: relative interface residual "
            f"{self.residuals[-1]:.3e} > tolerance {tolerance:.1e} after {len(self.residuals)} "
            f"iterations (residuals {_some(self.residuals)}; smallest {min(self.residuals):.2e})"
        )


SHOWN_RESIDUALS = 4
"""Residuals a coupling failure shows at each end of the list (100 iterations made a line of
1,200 characters)."""


def _some(residuals: Sequence[float]) -> str:
    """The first and last :data:`SHOWN_RESIDUALS` of ``residuals``, the others counted."""
    shown = [f"{r:.2e}" for r in residuals]
    if len(shown) > 2 * SHOWN_RESIDUALS + 1:
        hidden = len(shown) - 2 * SHOWN_RESIDUALS
        shown = [*shown[:SHOWN_RESIDUALS], f"... {hidden} more ...", *shown[-SHOWN_RESIDUALS:]]
    return ", ".join(shown)


@dataclass
class StepResult:
    """The converged step: the interface displacement ``x̃`` and the residual history."""

    displacement: np.ndarray
    residuals: list[float] = field(default_factory=list)

    @property
    def iterations(self) -> int:
        return len(self.residuals)


def couple_step(
    fluid: InterfaceSolver,
    solid: InterfaceSolver,
    acceleration: Acceleration,
    predictor: Predictor,
    comm: MPI.Comm,
    *,
    tolerance: float,
    max_iterations: int,
    step: int = 0,
    t: float | None = None,
    unknown: InterfaceUnknown | None = None,
    weights: np.ndarray | None = None,
) -> StepResult:
    """Dirichlet–Neumann iterations of one time step (ending at ``t``) until
    ``|x̃ − x| / |x̃| <= tolerance``.

    The first input is ``x_0 = predictor.predict(t)``. Iteration k:
    ``traction = fluid.solve(x_k)``, ``x̃_k = solid.solve(traction)``. Converged: both solvers
    ``advance()``, the acceleration ends the step, ``x̃_k`` is recorded in the predictor and
    returned. Otherwise ``x_{k+1} = acceleration.next_input(x_k, x̃_k)`` and both solvers
    ``restore_state()`` to the checkpoint saved at the start of the step.

    With an ``unknown`` (:class:`InterfaceUnknown`) the iterates are its z: the fluid takes z,
    the output is z̃ = [x̃, the fluid's forces] (Robin–Neumann), and the residual is that of
    z and z̃ times ``weights`` (:meth:`InterfaceUnknown.weights`; None: as they are); the
    returned displacement is x̃ all the same.

    Raises:
        CouplingNotConverged: after ``max_iterations`` iterations, with the solvers restored to
            the start of the step (collectively: every rank sees the same global residuals).
    """
    z = predictor.predict(t)
    fluid.save_state()
    solid.save_state()
    acceleration.start_step(weights)
    residuals: list[float] = []
    for k in range(max_iterations):
        if k > 0:
            fluid.restore_state()
            solid.restore_state()
        forces = fluid.solve(z)
        x_tilde = solid.solve(forces)
        z_tilde = unknown.stack(x_tilde, forces) if unknown else x_tilde
        residuals.append(
            relative_residual(comm, _weighted(weights, z), _weighted(weights, z_tilde))
        )
        log.debug("step %d, coupling iteration %d: residual %.3e", step, k + 1, residuals[-1])
        if residuals[-1] <= tolerance:
            fluid.advance()
            solid.advance()
            acceleration.end_step()
            predictor.record(z_tilde, t)
            return StepResult(x_tilde, residuals)
        z = acceleration.next_input(z, z_tilde)
    fluid.restore_state()
    solid.restore_state()
    raise CouplingNotConverged(step, residuals, tolerance)
