"""The exact linear solution of Womersley flow in a deformable thick-walled tube (issue #28).

Model. Blood (ρ_f, μ) fills 0 ≤ r ≤ a inside an elastic tube wall a ≤ r ≤ b = a + h
(E, ν, ρ_s), infinite in z, axisymmetric, no swirl; the outer surface r = b is traction-free
(no tethering). The fluid is the linearised incompressible Navier–Stokes system (no
convection), ρ_f ∂u/∂t = −∇p + μ ∇²u, ∇·u = 0; the wall is linear elastic with 3D Lamé
constants λ = Eν/((1+ν)(1−2ν)), G = E/(2(1+ν)) (what the code's St. Venant–Kirchhoff wall
linearises to; not plane strain), ρ_s ∂²w/∂t² = (λ+2G) ∇(∇·w) − G ∇×∇×w.

Conventions. Every field is Re[X(r) e^{i(ωt − kz)}], ω = 2πf, so ∂/∂t = iω and
∂/∂z = −ik; the complex wave number k has Re k > 0 (the wave travels in +z) and Im k < 0 (it
decays as it goes). Components are listed axial first, (z, r), as in the code's meshes.

Fluid. ∇·u = 0 makes p harmonic, p = A I₀(kr). The velocity is the potential part −∇p/(iωρ_f)
plus a viscous part u_h with iωρ_f u_h = μ ∇²u_h, ∇·u_h = 0: u_h,z = B I₀(κr),
u_h,r = (ik/κ) B I₁(κr), κ² = k² + iωρ_f/μ. Thus

    u_z = (k/(ωρ_f)) A I₀(kr) + B I₀(κr),   u_r = (ik/(ωρ_f)) A I₁(kr) + (ik/κ) B I₁(κr),
    σ_rr = −p + 2μ ∂u_r/∂r,   σ_rz = μ (∂u_r/∂z + ∂u_z/∂r).

Wall. w = ∇φ + ∇×(ψ e_θ), φ = C₁ I₀(qr) + C₂ K₀(qr), ψ = D₁ I₁(sr) + D₂ K₁(sr),
q² = k² − ω²/c_p², s² = k² − ω²/c_s², c_p² = (λ+2G)/ρ_s, c_s² = G/ρ_s:

    w_r = ∂φ/∂r − ∂ψ/∂z,   w_z = ∂φ/∂z + (1/r) ∂(rψ)/∂r,   ∇·w = ∇²φ = (q² − k²) φ,
    σ_rr = λ ∇·w + 2G ∂w_r/∂r,   σ_rz = G (∂w_r/∂z + ∂w_z/∂r),
    σ_θθ = λ ∇·w + 2G w_r/r,     σ_zz = λ ∇·w + 2G ∂w_z/∂z.

Conditions. At r = a the fluid moves with the wall, u = iω w (both components), and the
tractions agree (σ_rr, σ_rz continuous); at r = b, σ_rr = σ_rz = 0. These are six homogeneous
equations M(k) x = 0 in x = (A, B, C₁, C₂, D₁, D₂). The dispersion relation det M(k) = 0 is
solved by complex Newton (secant) iterations on the determinant of M scaled by fixed row and
column equilibration factors (M's entries span many orders of magnitude), started from the
thin-wall estimate below; :func:`wave_number` is the root nearest it (the pressure wave; the
relation has other roots: axial and higher radial modes). The null vector, scaled to A = the
pressure amplitude on the axis (p(0, 0, t) = P cos ωt), gives the coefficients.

Thin wall. Womersley's (1955) frequency equation for a free (untethered) thin elastic tube,
as Filonova et al. (2020) quote it,

    (1−g)(1−ν²) v² − [2 + m(1−g) + g(½ − 2ν)] v + g + 2m = 0,
    v = E h/((1−ν²) ρ_f a c²),  m = ρ_s h/(ρ_f a),  g = 2 J₁(Λ)/(Λ J₀(Λ)),  Λ = i^{3/2} α,
    α = a sqrt(ωρ_f/μ),

is a quadratic in v with two roots; :func:`thin_wall_wave_speed` returns the complex c
(k = ω/c) of the root nearer the tethered tube's c₀ sqrt((1−g)/(1−ν²)),
c₀ = sqrt(E h/(2ρ_f a)) (Moens–Korteweg); the other root is the wall's axial (bar) wave. For
an inviscid massless wall (g = m = 0) the chosen root is exactly c₀.

Womersley's theory is a long-wave one (|k| a ≪ 1) for h ≪ a: the thick wall tends to it as h → 0
at fixed E h (c₀ kept, so the wave stays long), e.g. −0.22 % in wave speed at h = 0.002 m,
E = 1 MPa, but not as h → 0 at fixed E (c₀ ∝ √h falls, |k| a grows to ≈ 1 at h = 0.002 m).
The default thick wall (h/a = 0.1) is 4.5 % slower than the thin-wall equation's wave.

Defaults. k = 0.143978 − 0.020727i 1/m, wave speed 0.87280 m/s, amplitude ratio per
wavelength 0.4047, w_r(a)/p(0) = 5.268e-4 + 1.82e-5i m/Pa; the thin-wall equation's
ω/Re k = 0.91357 m/s: all as solids4foam's womersleyTube verification data (as found;
tests/test_womersley_tube_exact.py).

Sources. J.R. Womersley, "Oscillatory motion of a viscous liquid in a thin-walled elastic
tube", Phil. Mag. 46 (1955) 199–221; V. Filonova et al., "Verification of the coupled-momentum
method with Womersley's deformable wall analytical solution", Int. J. Numer. Meth. Biomed. Eng.
36 (2020) e3266; the wall's potentials: the Helmholtz decomposition of linear elastodynamics in
cylindrical coordinates (e.g. K.F. Graff, "Wave motion in elastic solids", 1975), coupled to the
fluid above; the benchmark's set-up: solids4foam's womersleyTube case.

Usage::

    .venv/bin/python scripts/womersley_tube_exact.py

prints k, the wave speed, wavelength, amplitude ratio per wavelength, |w_r(a)|/|p(0)| and its
phase and the thin-wall values for the default parameters; its last line is one JSON object.
"""

from __future__ import annotations

import cmath
import json
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize, special


@dataclass(frozen=True)
class TubeParameters:
    """The tube (SI units): inner radius a, wall thickness h, the wall's E, ν, ρ_s, the
    fluid's ρ_f, μ, the frequency f and the pressure amplitude on the axis."""

    a: float = 1.0
    h: float = 0.1
    young: float = 20e3
    poisson: float = 0.3
    rho_solid: float = 1000.0
    rho_fluid: float = 1000.0
    mu: float = 5.0
    frequency: float = 0.02
    pressure_amplitude: float = 1.0

    @property
    def b(self) -> float:
        return self.a + self.h

    @property
    def omega(self) -> float:
        return 2 * math.pi * self.frequency

    @property
    def lame(self) -> tuple[float, float]:
        """(λ, G), the 3D Lamé constants."""
        E, nu = self.young, self.poisson
        return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))

    @property
    def womersley_number(self) -> float:
        return self.a * math.sqrt(self.omega * self.rho_fluid / self.mu)


# --- Bessel functions and their derivatives (complex arguments) -----------------------------


def _i0(x):
    return special.iv(0, x)


def _i1(x):
    return special.iv(1, x)


def _di1(x):
    """I₁'(x) = (I₀(x) + I₂(x))/2."""
    return 0.5 * (special.iv(0, x) + special.iv(2, x))


def _k0(x):
    return special.kv(0, x)


def _k1(x):
    return special.kv(1, x)


def _dk1(x):
    """K₁'(x) = −(K₀(x) + K₂(x))/2."""
    return -0.5 * (special.kv(0, x) + special.kv(2, x))


def _wave_numbers(params: TubeParameters, k: complex) -> tuple[complex, complex, complex]:
    """κ, q, s (principal square roots; the spans of the bases do not depend on the branch)."""
    lam, G = params.lame
    w = params.omega
    kappa = cmath.sqrt(k * k + 1j * w * params.rho_fluid / params.mu)
    q = cmath.sqrt(k * k - w * w * params.rho_solid / (lam + 2 * G))
    s = cmath.sqrt(k * k - w * w * params.rho_solid / G)
    return kappa, q, s


def _fluid_columns(params: TubeParameters, k: complex, r) -> dict[str, np.ndarray]:
    """The fluid's profiles per unit A (column 0) and per unit B (column 1): arrays of shape
    (2,) + r.shape for p, u_z, u_r, ∂u_z/∂r, ∂u_r/∂r, σ_rr, σ_rz."""
    r = np.asarray(r, dtype=float)
    kappa, _, _ = _wave_numbers(params, k)
    w, rho, mu = params.omega, params.rho_fluid, params.mu
    kr, cr = k * r, kappa * r
    c = k / (w * rho)
    p = np.stack([_i0(kr), np.zeros_like(cr)])
    uz = np.stack([c * _i0(kr), _i0(cr)])
    ur = np.stack([1j * c * _i1(kr), 1j * k / kappa * _i1(cr)])
    duz = np.stack([c * k * _i1(kr), kappa * _i1(cr)])
    dur = np.stack([1j * c * k * _di1(kr), 1j * k * _di1(cr)])
    srr = -p + 2 * mu * dur
    srz = mu * (-1j * k * ur + duz)
    return {"p": p, "u_z": uz, "u_r": ur, "du_z": duz, "du_r": dur, "s_rr": srr, "s_rz": srz}


def _solid_columns(params: TubeParameters, k: complex, r) -> dict[str, np.ndarray]:
    """The wall's profiles per unit C₁, C₂, D₁, D₂ (columns 0–3): arrays of shape
    (4,) + r.shape for w_z, w_r, ∂w_z/∂r, ∂w_r/∂r, ∇·w and the stresses."""
    r = np.asarray(r, dtype=float)
    _, q, s = _wave_numbers(params, k)
    lam, G = params.lame
    qr, sr = q * r, s * r
    zero = np.zeros_like(qr)
    # φ = I₀(qr): w_r = φ' = q I₁, w_z = −ik I₀.  φ = K₀(qr): w_r = −q K₁, w_z = −ik K₀.
    # ψ = I₁(sr): w_r = ik I₁, w_z = (rψ)'/r = s I₀.  ψ = K₁(sr): w_r = ik K₁, w_z = −s K₀.
    wr = np.stack([q * _i1(qr), -q * _k1(qr), 1j * k * _i1(sr), 1j * k * _k1(sr)])
    wz = np.stack([-1j * k * _i0(qr), -1j * k * _k0(qr), s * _i0(sr), -s * _k0(sr)])
    dwr = np.stack(
        [q * q * _di1(qr), -q * q * _dk1(qr), 1j * k * s * _di1(sr), 1j * k * s * _dk1(sr)]
    )
    dwz = np.stack([-1j * k * q * _i1(qr), 1j * k * q * _k1(qr), s * s * _i1(sr), s * s * _k1(sr)])
    # ∇·w = ∇²φ = (q² − k²) φ = −(ω²/c_p²) φ (the ∂²/∂z² = −k² part included).
    div = np.stack([(q * q - k * k) * _i0(qr), (q * q - k * k) * _k0(qr), zero, zero])
    srr = lam * div + 2 * G * dwr
    srz = G * (-1j * k * wr + dwz)
    stt = lam * div + 2 * G * wr / r
    szz = lam * div + 2 * G * (-1j * k * wz)
    return {
        "w_z": wz,
        "w_r": wr,
        "dw_z": dwz,
        "dw_r": dwr,
        "div": div,
        "s_rr": srr,
        "s_rz": srz,
        "s_tt": stt,
        "s_zz": szz,
    }


def system_matrix(params: TubeParameters, k: complex) -> np.ndarray:
    """M(k), the six conditions (rows: u_z − iω w_z, u_r − iω w_r, σ_rr and σ_rz jumps at
    r = a; σ_rr, σ_rz at r = b) on x = (A, B, C₁, C₂, D₁, D₂)."""
    iw = 1j * params.omega
    f = _fluid_columns(params, k, params.a)
    sa = _solid_columns(params, k, params.a)
    sb = _solid_columns(params, k, params.b)
    M = np.zeros((6, 6), dtype=complex)
    M[0, :2], M[0, 2:] = f["u_z"], -iw * sa["w_z"]
    M[1, :2], M[1, 2:] = f["u_r"], -iw * sa["w_r"]
    M[2, :2], M[2, 2:] = f["s_rr"], -sa["s_rr"]
    M[3, :2], M[3, 2:] = f["s_rz"], -sa["s_rz"]
    M[4, 2:] = sb["s_rr"]
    M[5, 2:] = sb["s_rz"]
    return M


def _equilibration(M: np.ndarray, sweeps: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Row and column factors (powers of 2) that bring every row's and column's largest entry
    of diag(dr) M diag(dc) near 1."""
    dr, dc = np.ones(M.shape[0]), np.ones(M.shape[1])
    A = np.abs(M)
    for _ in range(sweeps):
        dr = dr / 2.0 ** np.round(np.log2((A * dr[:, None] * dc[None, :]).max(axis=1)))
        dc = dc / 2.0 ** np.round(np.log2((A * dr[:, None] * dc[None, :]).max(axis=0)))
    return dr, dc


def thin_wall_wave_speed(params: TubeParameters) -> complex:
    """The complex wave speed c (k = ω/c) of Womersley's thin-wall frequency equation (module
    docstring), the root nearer the tethered tube's c₀ sqrt((1−g)/(1−ν²))."""
    E, nu, a, h = params.young, params.poisson, params.a, params.h
    rho = params.rho_fluid
    m = params.rho_solid * h / (rho * a)
    lam_ = cmath.exp(0.75j * math.pi) * params.womersley_number
    g = 2 * special.jve(1, lam_) / (lam_ * special.jve(0, lam_))  # scaled: large α too
    roots = np.roots([(1 - g) * (1 - nu**2), -(2 + m * (1 - g) + g * (0.5 - 2 * nu)), g + 2 * m])
    speeds = [cmath.sqrt(E * h / ((1 - nu**2) * rho * a * v)) for v in roots]
    c0 = math.sqrt(E * h / (2 * rho * a))
    tethered = c0 * cmath.sqrt((1 - g) / (1 - nu**2))
    return complex(min(speeds, key=lambda c: abs(c - tethered)))


def _determinant(params: TubeParameters, k0: complex):
    dr, dc = _equilibration(system_matrix(params, k0))
    return lambda k: np.linalg.det(dr[:, None] * system_matrix(params, k) * dc[None, :])


def wave_number(params: TubeParameters, k0: complex | None = None) -> complex:
    """The pressure wave's k: the root of det M(k) = 0 that secant iterations from the thin-wall
    estimate ω/c (or ``k0``) reach."""
    if k0 is None:
        k0 = params.omega / thin_wall_wave_speed(params)
    det = _determinant(params, k0)
    k0 = complex(k0)
    try:
        k = optimize.newton(det, k0, x1=k0 * (1 + 1e-3), tol=1e-13 * abs(k0), rtol=1e-11)
    except RuntimeError:
        # Thin, stiff walls make M(k) ill-conditioned (scipy's secant then wanders at ~1e-10
        # of k on some platforms: Debian 13's at h = 0.5 mm): settle for 1e-9 of k.
        k = optimize.newton(det, k0, x1=k0 * (1 + 1e-3), tol=1e-9 * abs(k0), rtol=1e-9)
    k = complex(k)
    return k if k.real > 0 else -k


@dataclass
class WomersleyTube:
    """The exact solution for ``params``: k and the coefficients x = (A, B, C₁, C₂, D₁, D₂)
    (A = the axis pressure's amplitude). The field methods take broadcastable arrays r, z, t
    and return real fields; the ``*_amplitude(s)`` methods the complex profiles X(r)."""

    params: TubeParameters = field(default_factory=TubeParameters)
    k: complex = field(init=False)
    coefficients: np.ndarray = field(init=False)

    def __post_init__(self):
        self.k = wave_number(self.params)
        M = system_matrix(self.params, self.k)
        dr, dc = _equilibration(M)
        _, sv, vh = np.linalg.svd(dr[:, None] * M * dc[None, :])
        x = vh[-1].conj() * dc
        self.coefficients = x / x[0] * self.params.pressure_amplitude
        self.singular_values = sv

    # complex profiles
    def fluid_amplitudes(self, r) -> dict[str, np.ndarray]:
        """p, u_z, u_r, their r-derivatives and σ_rr, σ_rz of the fluid at r (complex)."""
        cols = _fluid_columns(self.params, self.k, r)
        x = self.coefficients[:2]
        return {name: np.tensordot(x, v, axes=1) for name, v in cols.items()}

    def wall_amplitudes(self, r) -> dict[str, np.ndarray]:
        """w_z, w_r, their r-derivatives, ∇·w and σ_rr, σ_rz, σ_θθ, σ_zz of the wall at r."""
        cols = _solid_columns(self.params, self.k, r)
        x = self.coefficients[2:]
        return {name: np.tensordot(x, v, axes=1) for name, v in cols.items()}

    def wall_radial_amplitude(self, r) -> np.ndarray:
        return self.wall_amplitudes(r)["w_r"]

    def wall_axial_amplitude(self, r) -> np.ndarray:
        return self.wall_amplitudes(r)["w_z"]

    # real fields
    def _wave(self, z, t, order: int = 0):
        z, t = np.asarray(z, dtype=float), np.asarray(t, dtype=float)
        w = self.params.omega
        return (1j * w) ** order * np.exp(1j * (w * t - self.k * z))

    def pressure(self, r, z, t) -> np.ndarray:
        return np.real(self.fluid_amplitudes(r)["p"] * self._wave(z, t))

    def fluid_velocity(self, r, z, t) -> tuple[np.ndarray, np.ndarray]:
        """(u_z, u_r)."""
        f, e = self.fluid_amplitudes(r), self._wave(z, t)
        return np.real(f["u_z"] * e), np.real(f["u_r"] * e)

    def _wall(self, r, z, t, order):
        s, e = self.wall_amplitudes(r), self._wave(z, t, order)
        return np.real(s["w_z"] * e), np.real(s["w_r"] * e)

    def wall_displacement(self, r, z, t) -> tuple[np.ndarray, np.ndarray]:
        """(w_z, w_r)."""
        return self._wall(r, z, t, 0)

    def wall_velocity(self, r, z, t) -> tuple[np.ndarray, np.ndarray]:
        return self._wall(r, z, t, 1)

    def wall_acceleration(self, r, z, t) -> tuple[np.ndarray, np.ndarray]:
        return self._wall(r, z, t, 2)

    # derived numbers
    @property
    def wave_speed(self) -> float:
        """ω/Re k (m/s), the phase speed."""
        return self.params.omega / self.k.real

    @property
    def wavelength(self) -> float:
        return 2 * math.pi / self.k.real

    @property
    def amplitude_ratio_per_wavelength(self) -> float:
        """exp(2π Im k/Re k): how much of an amplitude is left one wavelength on."""
        return math.exp(2 * math.pi * self.k.imag / self.k.real)

    @property
    def wall_radial_per_pressure_complex(self) -> complex:
        """w_r(a)/p(0) (m/Pa), complex: the same at every z and t."""
        return complex(self.wall_radial_amplitude(self.params.a)) / self.coefficients[0]

    @property
    def wall_radial_per_pressure(self) -> float:
        """|w_r(a)|/|p(0)| (m/Pa)."""
        return abs(self.wall_radial_per_pressure_complex)


def summary(params: TubeParameters | None = None) -> dict[str, float]:
    params = params or TubeParameters()
    tube = WomersleyTube(params)
    ratio = tube.wall_radial_per_pressure_complex
    c_thin = thin_wall_wave_speed(params)
    k_thin = params.omega / c_thin
    return {
        "k_re": tube.k.real,
        "k_im": tube.k.imag,
        "wave_speed": tube.wave_speed,
        "wavelength": tube.wavelength,
        "amplitude_ratio_per_wavelength": tube.amplitude_ratio_per_wavelength,
        "wr_per_p": tube.wall_radial_per_pressure,
        "wr_per_p_re": ratio.real,
        "wr_per_p_im": ratio.imag,
        "wr_per_p_phase_deg": math.degrees(cmath.phase(ratio)),
        "thin_c_re": c_thin.real,
        "thin_c_im": c_thin.imag,
        "thin_k_re": k_thin.real,
        "thin_k_im": k_thin.imag,
        "thin_wave_speed": params.omega / k_thin.real,
        "thin_amplitude_ratio_per_wavelength": math.exp(2 * math.pi * k_thin.imag / k_thin.real),
        "moens_korteweg": math.sqrt(params.young * params.h / (2 * params.rho_fluid * params.a)),
    }


def main() -> dict[str, float]:
    params = TubeParameters()
    s = summary(params)
    print(f"Womersley flow in a thick-walled elastic tube: {params}")
    print(f"  Womersley number α = {params.womersley_number:.4f}")
    print(f"  k = {s['k_re']:.6f} {s['k_im']:+.6f}i 1/m")
    print(f"  wave speed ω/Re k = {s['wave_speed']:.5f} m/s, wavelength {s['wavelength']:.4f} m")
    print(f"  amplitude ratio per wavelength = {s['amplitude_ratio_per_wavelength']:.4f}")
    print(
        f"  w_r(a)/p(0) = {s['wr_per_p_re']:.5e} {s['wr_per_p_im']:+.5e}i m/Pa, "
        f"|.| = {s['wr_per_p']:.5e} m/Pa, phase {s['wr_per_p_phase_deg']:.3f}°"
    )
    print(
        f"  thin wall (Womersley 1955): c = {s['thin_c_re']:.5f} {s['thin_c_im']:+.5f}i m/s, "
        f"k = {s['thin_k_re']:.6f} {s['thin_k_im']:+.6f}i 1/m, ω/Re k = "
        f"{s['thin_wave_speed']:.5f} m/s, amplitude ratio per wavelength "
        f"{s['thin_amplitude_ratio_per_wavelength']:.4f}"
    )
    print(f"  Moens–Korteweg c₀ = {s['moens_korteweg']:.5f} m/s")
    print(json.dumps(s))
    return s
