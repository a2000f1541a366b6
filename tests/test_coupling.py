"""Interface accelerations on known fixed-point maps and the Dirichlet–Neumann loop with fake
linear solvers. Vectors are split over the ranks, so the MPI-global inner products matter; every
check runs once on the distributed vectors (COMM_WORLD) and once on whole ones (COMM_SELF), and
the two must take the same iterations to the same answer."""

from __future__ import annotations

from mpi4py import MPI

import numpy as np
import pytest

from fsi import config
from fsi.coupled import coupling as cp

COMMS = {"world": MPI.COMM_WORLD, "self": MPI.COMM_SELF}


def rows(comm: MPI.Comm, n: int) -> np.ndarray:
    """The global indices this rank owns of a vector of length n (contiguous blocks)."""
    return np.array_split(np.arange(n), comm.size)[comm.rank]


def gather(comm: MPI.Comm, x: np.ndarray) -> np.ndarray:
    return np.concatenate(comm.allgather(x))


def symmetric_matrix(n: int, eigenvalues: np.ndarray, seed: int = 0) -> np.ndarray:
    """Q diag(eigenvalues) Qᵀ with a random orthogonal Q."""
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(n, n)))
    return q @ np.diag(eigenvalues) @ q.T


class Map:
    """The fixed-point map H(x) = A x + b + eps sin(x) on distributed vectors."""

    def __init__(self, comm, A, b, eps=0.0):
        self.comm, self.A, self.b, self.eps = comm, A, b, eps
        self.rows = rows(comm, len(b))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return (self.A @ gather(self.comm, x) + self.b)[self.rows] + self.eps * np.sin(x)


def iterate(acceleration, H, x0, comm, tolerance=1e-10, max_iterations=200):
    """Fixed-point iterations of one step; returns (evaluations of H, x̃, residuals)."""
    acceleration.start_step()
    x, residuals = x0.copy(), []
    for _ in range(max_iterations):
        x_tilde = H(x)
        residuals.append(cp.relative_residual(comm, x, x_tilde))
        if residuals[-1] <= tolerance:
            acceleration.end_step()
            return len(residuals), x_tilde, residuals
        x = acceleration.next_input(x, x_tilde)
    raise AssertionError(f"no convergence: {residuals[-5:]}")


def run_both(make_acceleration, A, b, eps=0.0, tolerance=1e-10, max_iterations=200):
    """The same problem on COMM_WORLD (distributed) and COMM_SELF: equal counts and answers."""
    results = {}
    for name, comm in COMMS.items():
        H = Map(comm, A, b, eps)
        count, x_tilde, residuals = iterate(
            make_acceleration(comm), H, np.zeros(len(H.rows)), comm, tolerance, max_iterations
        )
        results[name] = count, gather(comm, x_tilde), residuals
    (n_w, x_w, r_w), (n_s, x_s, r_s) = results["world"], results["self"]
    assert n_w == n_s
    np.testing.assert_allclose(x_w, x_s, rtol=1e-9, atol=1e-12)  # only summation order differs
    np.testing.assert_allclose(r_w, r_s, rtol=1e-6, atol=1e-14)
    return n_w, x_w


def test_global_dot_and_norm_match_the_whole_vectors():
    comm = MPI.COMM_WORLD
    a, b = np.arange(7.0), np.linspace(1, 2, 7)
    mine = rows(comm, 7)
    assert cp.dot(comm, a[mine], b[mine]) == pytest.approx(a @ b, rel=1e-14)
    assert cp.norm(comm, a[mine]) == pytest.approx(np.linalg.norm(a), rel=1e-14)


# --------------------------------------------------------------------------------------------
# Accelerations on fixed-point maps

N = 10
B = np.random.default_rng(3).normal(size=N)


def test_constant_relaxation_with_the_exact_factor_converges_in_one_update():
    # H(x) = −x + b: x + ω (H(x) − x) = (1 − 2ω) x + ω b is the fixed point b/2 for ω = 1/2.
    count, x = run_both(lambda c: cp.ConstantRelaxation(c, 0.5), -np.eye(N), B)
    assert count == 2
    np.testing.assert_allclose(x, B / 2, rtol=1e-14)


def test_aitken_on_a_scaled_identity_is_exact_after_two_updates():
    # H(x) = a x + b with a = −3 (plain iteration diverges, like the added-mass effect): the
    # residuals are all parallel and Aitken's second ω = 1/(1 − a) = 0.25 is the secant root.
    a = -3.0
    count, x = run_both(lambda c: cp.Aitken(c, 0.5, 1.0), a * np.eye(N), B)
    assert count == 3  # evaluations at x_0, x_1 and the exact x_2
    np.testing.assert_allclose(x, B / (1 - a), rtol=1e-12)


def test_aitken_and_iqn_on_a_linear_map_with_spread_eigenvalues():
    # Symmetric, eigenvalues in [−3, −0.2]: plain iteration diverges; relaxation needs ω < 0.5
    # and contracts at best by (λmax − λmin)/(2 − λmax − λmin) = 0.62 per iteration.
    A = symmetric_matrix(N, np.linspace(-3.0, -0.2, N))
    exact = np.linalg.solve(np.eye(N) - A, B)
    n_const, _ = run_both(lambda c: cp.ConstantRelaxation(c, 0.3), A, B)
    n_aitken, x_aitken = run_both(lambda c: cp.Aitken(c, 0.3, 1.0), A, B)
    n_iqn, x_iqn = run_both(lambda c: cp.IQNILS(c, 0.3), A, B)
    for x in (x_aitken, x_iqn):  # |x̃ − x*| <= |A (A − I)⁻¹| |x̃ − x| <= 0.75 · 1e-10 |x̃|
        assert np.linalg.norm(x - exact) <= 1e-10 * np.linalg.norm(exact)
    # measured (bookworm and trixie, 1 and 2 ranks): constant 52, Aitken 22, IQN-ILS 12
    assert n_iqn <= N + 2 < n_aitken < n_const
    # ω = 0.3: worst contraction |1 + 0.3 (−0.2 − 1)| = 0.64; log(1e-10) / log(0.64) = 51.6
    assert n_const == 52


def test_aitken_cap_holds_omega_at_omega_max():
    # Aitken would choose 0.25 on H = −3x + b; capped at 0.1 it is constant relaxation by 0.1.
    A = -3.0 * np.eye(N)
    n_capped, _ = run_both(lambda c: cp.Aitken(c, 0.1, omega_max=0.1), A, B)
    n_const, _ = run_both(lambda c: cp.ConstantRelaxation(c, 0.1), A, B)
    assert n_capped == n_const
    # contraction |1 − 0.1·4| = 0.6 from r_0 = |b|: 0.6^k <= 1e-10 · |x̃|/|b| ~ 0.25e-10
    assert n_const == 1 + int(np.ceil(np.log(0.25e-10) / np.log(0.6)))


def test_aitken_carries_omega_over_to_the_next_step():
    comm = MPI.COMM_WORLD
    H = Map(comm, -3.0 * np.eye(N), B)
    aitken = cp.Aitken(comm, 0.5, 1.0)
    assert iterate(aitken, H, np.zeros(len(H.rows)), comm)[0] == 3
    assert aitken.omega == pytest.approx(0.25, rel=1e-12)
    # The next step starts with the carried-over ω = 0.25, exact for this map: one update.
    H.b = 2 * B
    count, x, _ = iterate(aitken, H, np.zeros(len(H.rows)), comm)
    assert count == 2
    np.testing.assert_allclose(gather(comm, x), 2 * B / 4, rtol=1e-12)


def test_iqn_ils_solves_an_n_dimensional_linear_map_in_n_plus_one_updates():
    # Non-symmetric, spectral radius > 1: plain iteration diverges. The secant columns span the
    # GMRES Krylov space: with n columns (after n + 1 evaluations) the model is exact, so the
    # (n + 1)-th update hits the fixed point and the (n + 2)-th evaluation confirms it.
    rng = np.random.default_rng(1)
    A = rng.normal(size=(N, N)) * 1.5 / np.sqrt(N)
    assert max(abs(np.linalg.eigvals(A))) > 1
    count, x = run_both(lambda c: cp.IQNILS(c, 0.5), A, B, tolerance=1e-10)
    assert count - 1 <= N + 1  # updates
    exact = np.linalg.solve(np.eye(N) - A, B)
    assert np.linalg.norm(x - exact) <= 1e-9 * np.linalg.norm(exact)


@pytest.mark.parametrize("name,make,expected", [
    ("aitken", lambda c: cp.Aitken(c, 0.3, 1.0), 24),
    ("iqn-ils", lambda c: cp.IQNILS(c, 0.3), 15),
])  # fmt: skip
def test_mildly_nonlinear_map(name, make, expected):
    # H(x) = A x + b + 0.2 sin(x): the Jacobian A + 0.2 diag(cos x) stays within 0.2 of A's.
    A = symmetric_matrix(N, np.linspace(-3.0, -0.2, N))
    count, x = run_both(make, A, B, eps=0.2)
    fixed_point_residual = A @ x + B + 0.2 * np.sin(x) - x
    assert np.linalg.norm(fixed_point_residual) <= 1e-9 * np.linalg.norm(x)
    # measured on bookworm and trixie, 1 and 2 ranks; allow ±2 for round-off in the secants
    assert abs(count - expected) <= 2


def test_iqn_reuse_reduces_iterations_on_slowly_varying_problems():
    # Twelve steps of H_s(x) = A_s x + b_s with A_s, b_s drifting by 0.1 % per step.
    n = 40
    A0 = symmetric_matrix(n, np.linspace(-4.0, -0.1, n), seed=4)
    drift = symmetric_matrix(n, np.linspace(-1, 1, n), seed=5)
    b0 = np.random.default_rng(6).normal(size=n)
    totals = {}
    for reuse in (0, 4):
        counts = {}
        for name, comm in COMMS.items():
            iqn = cp.IQNILS(comm, 0.2, reuse=reuse)
            H = Map(comm, A0, b0)
            x = np.zeros(len(H.rows))
            counts[name] = []
            for s in range(12):
                H.A, H.b = A0 + 0.001 * s * drift, b0 * (1 + 0.001 * s)
                count, x, _ = iterate(iqn, H, x, comm, tolerance=1e-8)
                counts[name].append(count)
        assert counts["world"] == counts["self"]
        totals[reuse] = sum(counts["world"])
    # measured: 186 without reuse (21, then 15 per step), 71 with the last 4 steps' columns
    # (21, 11, 5, then 3-5 per step)
    assert totals[4] <= 0.5 * totals[0]


def test_qr_filter_drops_a_duplicated_column():
    comm = MPI.COMM_WORLD
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=N), rng.normal(size=N)
    mine = rows(comm, N)
    columns = [a[mine], b[mine], a[mine].copy(), (2 * a - b)[mine], np.zeros(len(mine))]
    Q, R, kept = cp.filtered_qr(comm, columns, threshold=1e-8)
    assert kept == [0, 1]  # the copy, the combination and the zero column are dependent
    QtQ = comm.allreduce(Q.T @ Q, op=MPI.SUM)
    np.testing.assert_allclose(QtQ, np.eye(2), atol=1e-14)
    np.testing.assert_allclose(Q @ R, np.column_stack([a[mine], b[mine]]), atol=1e-14)
    # A perturbation above the threshold is kept, one below it is dropped.
    near = a + 1e-6 * np.linalg.norm(a) * b / np.linalg.norm(b)
    assert cp.filtered_qr(comm, [a[mine], near[mine]], threshold=1e-8)[2] == [0, 1]
    assert cp.filtered_qr(comm, [a[mine], near[mine]], threshold=1e-4)[2] == [0]


def test_iqn_ils_filters_a_repeated_secant_pair():
    # Feeding the same (x, x̃) twice creates a zero column (Δr = 0): without the filter R would
    # be singular; with it the update falls back to the relaxation step.
    comm = MPI.COMM_WORLD
    mine = rows(comm, N)
    iqn = cp.IQNILS(comm, 0.5)
    iqn.start_step()
    x, x_tilde = np.ones(N)[mine], B[mine]
    iqn.next_input(x, x_tilde)
    again = iqn.next_input(x, x_tilde)
    assert (iqn.columns_used, iqn.columns_dropped) == (0, 1)
    np.testing.assert_allclose(again, x + 0.5 * (x_tilde - x))


# --------------------------------------------------------------------------------------------
# Predictor


def test_predictor_extrapolates_polynomials_exactly():
    x0 = np.array([1.0, -2.0])
    for order, f in [(0, lambda t: x0), (1, lambda t: x0 * (1 + 3 * t)),
                     (2, lambda t: x0 * (1 + 3 * t - 5 * t**2)),
                     (3, lambda t: x0 * (1 + 3 * t - 5 * t**2 + 7 * t**3))]:  # fmt: skip
        p = cp.Predictor(order)
        times = [-0.05, 0.0, 0.1, 0.25]  # unequal steps; the oldest drops out below cubic
        for t in times:
            p.record(f(t), t)
        np.testing.assert_allclose(p.predict(0.3), f(0.3), rtol=1e-12)
        if order < 3:  # one degree more is not extrapolated exactly
            for t in times:
                p.record(f(t) + x0 * t ** (order + 1), t)
            assert not np.allclose(p.predict(0.3), f(0.3) + x0 * 0.3 ** (order + 1), rtol=1e-6)
    p = cp.Predictor("quadratic")  # without times: equal steps, 3 x_n − 3 x_{n−1} + x_{n−2}
    for k in range(3):
        p.record(np.array([k**2 + 1.0]))
    np.testing.assert_allclose(p.predict(), [3**2 + 1.0])
    p = cp.Predictor("cubic")  # equal steps: 4 x_n − 6 x_{n−1} + 4 x_{n−2} − x_{n−3}
    for k in range(5):
        p.record(np.array([k**3 - 2.0 * k]))
    np.testing.assert_allclose(p.predict(), [5**3 - 10.0])
    np.testing.assert_allclose(p.predict(), [4 * 56 - 6 * 21 + 4 * 4 - 1 * -1.0])
    p = cp.Predictor("quadratic")  # with one value only: constant
    p.record(x0, 0.0)
    np.testing.assert_allclose(p.predict(1.0), x0)
    with pytest.raises(ValueError, match="record the initial"):
        cp.Predictor(1).predict(1.0)


# --------------------------------------------------------------------------------------------
# The Dirichlet–Neumann loop with fake linear solvers


class FakeSolver:
    """A linear "solver" ``output = K input + c(step)``; its state is the step number. It
    insists on the protocol: a second solve needs restore_state() first."""

    def __init__(self, comm, K, c_of_step, n_in):
        self.comm, self.K, self.c_of_step = comm, K, c_of_step
        self.rows = rows(comm, K.shape[0])
        self.step, self.saved, self.dirty = 0, None, False
        self.calls = {"save_state": 0, "restore_state": 0, "solve": 0, "advance": 0}

    def save_state(self):
        self.saved, self.dirty = self.step, False
        self.calls["save_state"] += 1

    def restore_state(self):
        self.step, self.dirty = self.saved, False
        self.calls["restore_state"] += 1

    def solve(self, interface_input):
        assert not self.dirty, "solved twice without restore_state()"
        self.dirty = True
        self.calls["solve"] += 1
        full = gather(self.comm, interface_input)
        return (self.K @ full + self.c_of_step(self.step + 1))[self.rows]

    def advance(self):
        self.step, self.dirty = self.step + 1, False
        self.calls["advance"] += 1


# Fluid: traction t = K_f d + b(t_n); solid: d = S t. S K_f has eigenvalues in [−4, −0.3] (the
# fluid pushes back against the wall motion: the added-mass effect).
N_DN = 12
S = symmetric_matrix(N_DN, np.linspace(0.5, 2.0, N_DN), seed=8)  # compliance, SPD
K_F = np.linalg.solve(S, symmetric_matrix(N_DN, np.linspace(-4.0, -0.3, N_DN), seed=9))
B_DN = np.random.default_rng(10).normal(size=N_DN)
M = S @ K_F  # the interface map d ↦ S (K_f d + b)


def traction_load(step: int) -> np.ndarray:
    return B_DN * np.sin(0.3 * step)


def coupled_solution(step: int) -> np.ndarray:
    """d = S (K_f d + b) ⇔ (I − S K_f) d = S b, solved directly."""
    return np.linalg.solve(np.eye(N_DN) - M, S @ traction_load(step))


def run_coupler(comm, coupling: config.Coupling, steps: int = 6):
    fluid = FakeSolver(comm, K_F, traction_load, N_DN)
    solid = FakeSolver(comm, S, lambda step: np.zeros(N_DN), N_DN)
    acceleration = cp.from_config(coupling, comm)
    predictor = cp.predictor_from_config(coupling)
    predictor.record(np.zeros(len(rows(comm, N_DN))), 0.0)
    results = []
    for n in range(1, steps + 1):
        results.append(
            cp.couple_step(
                fluid,
                solid,
                acceleration,
                predictor,
                comm,
                tolerance=coupling.tolerance,
                max_iterations=coupling.max_iterations,
                step=n,
                t=0.1 * n,
            )
        )
    return fluid, solid, results


@pytest.mark.parametrize("acceleration", ["constant", "aitken", "iqn-ils"])
def test_coupler_reproduces_the_coupled_solution(acceleration):
    coupling = config.Coupling(
        acceleration=acceleration, tolerance=1e-8, max_iterations=200, initial_relaxation=0.3
    )
    # |d̃ − d*| <= |M (M − I)⁻¹| |d̃ − d| <= |M (M − I)⁻¹| · tol · |d̃|: the tolerance's meaning.
    amplification = np.linalg.norm(M @ np.linalg.inv(M - np.eye(N_DN)), 2)
    iterations = {}
    for name, comm in COMMS.items():
        fluid, solid, results = run_coupler(comm, coupling)
        iterations[name] = [r.iterations for r in results]
        for n, result in enumerate(results, start=1):
            d = gather(comm, result.displacement)
            exact = coupled_solution(n)
            assert np.linalg.norm(d - exact) <= amplification * 1e-8 * np.linalg.norm(d) * 1.0001
            assert result.residuals[-1] <= 1e-8 < min(result.residuals[:-1], default=1)
        total = sum(iterations[name])
        for solver in (fluid, solid):
            assert solver.calls == {
                "save_state": 6,
                "restore_state": total - 6,
                "solve": total,
                "advance": 6,
            }
    assert iterations["world"] == iterations["self"]
    if acceleration == "iqn-ils":  # reused columns: later steps need few iterations
        assert max(iterations["world"][2:]) <= 4


def test_coupler_iteration_counts_rank_the_accelerations():
    counts = {}
    for acceleration in ("constant", "aitken", "iqn-ils"):
        coupling = config.Coupling(
            acceleration=acceleration, tolerance=1e-8, max_iterations=200, initial_relaxation=0.3
        )
        counts[acceleration] = sum(r.iterations for r in run_coupler(MPI.COMM_WORLD, coupling)[2])
    assert counts["iqn-ils"] < counts["aitken"] < counts["constant"]


def test_coupler_raises_after_max_iterations_with_the_residual_history():
    comm = MPI.COMM_WORLD
    # Unrelaxed (ω = 1) Dirichlet–Neumann diverges: |eigenvalue| of S K_f up to 4 > 1.
    coupling = config.Coupling(acceleration="constant", initial_relaxation=1.0, max_iterations=5)
    fluid = FakeSolver(comm, K_F, traction_load, N_DN)
    solid = FakeSolver(comm, S, lambda step: np.zeros(N_DN), N_DN)
    predictor = cp.Predictor("linear")
    predictor.record(np.zeros(len(rows(comm, N_DN))), 0.0)
    with pytest.raises(cp.CouplingNotConverged) as e:
        cp.couple_step(
            fluid,
            solid,
            cp.from_config(coupling, comm),
            predictor,
            comm,
            tolerance=coupling.tolerance,
            max_iterations=5,
            step=7,
            t=0.1,
        )
    assert e.value.step == 7 and len(e.value.residuals) == 5
    assert e.value.residuals[-1] > coupling.tolerance
    assert "step 7" in str(e.value) and "5 iterations" in str(e.value)
    for solver in (fluid, solid):  # back at the start of the step, nothing advanced
        assert solver.calls["advance"] == 0 and solver.step == 0 and not solver.dirty
        assert solver.calls["restore_state"] == 5


def test_accelerations_from_the_configuration():
    comm = MPI.COMM_WORLD
    case = config.from_dict(
        {
            "coupling": {
                "acceleration": "iqn-ils",
                "initial_relaxation": 0.4,
                "iqn_reuse": 3,
                "iqn_filter": 1e-6,
                "predictor": "quadratic",
            }
        }
    )
    iqn = cp.from_config(case.coupling, comm)
    assert isinstance(iqn, cp.IQNILS)
    assert (iqn.omega, iqn.reuse, iqn.threshold) == (0.4, 3, 1e-6)
    assert cp.predictor_from_config(case.coupling).order == 2
    aitken = cp.from_config(config.Coupling(initial_relaxation=0.2, max_relaxation=0.8), comm)
    assert isinstance(aitken, cp.Aitken) and (aitken.omega, aitken.omega_max) == (0.2, 0.8)
    with pytest.raises(config.ConfigError, match="coupling.max_relaxation"):
        config.from_dict({"coupling": {"initial_relaxation": 0.5, "max_relaxation": 0.4}})


def test_a_coupling_failure_shows_the_ends_of_its_residuals():
    """100 iterations made one line of 1,200 characters of residuals: the message shows the
    first and last 4, how many are left out, and the smallest."""
    residuals = [1.0] * 50 + [0.5**k for k in range(1, 51)]
    message = str(cp.CouplingNotConverged(1, residuals, 1e-8))
    assert "(residuals 1.00e+00, 1.00e+00, 1.00e+00, 1.00e+00, ... 92 more ..., " in message
    assert "8.88e-16; smallest 8.88e-16)" in message and len(message) < 300, message
    few = str(cp.CouplingNotConverged(2, [1.0, 0.5, 0.25], 1e-8))
    assert "(residuals 1.00e+00, 5.00e-01, 2.50e-01; smallest 2.50e-01)" in few
