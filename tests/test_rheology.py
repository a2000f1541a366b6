"""Viscosity laws: limits, special cases, regularisations, UFL = numpy, and their config errors."""

import typing

from mpi4py import MPI

import dolfinx.fem
import dolfinx.mesh
import numpy as np
import pytest
import support_run
import ufl

from fsi import compat, config
from fsi.config import reader
from fsi.physics import rheology

MODELS = ["newtonian", "carreau", "carreau_yasuda", "cross", "power_law", "casson"]


def law_of(model: str, **parameters) -> rheology.ViscosityLaw:
    return rheology.from_config(
        config.from_dict({"fluid": {"rheology": {"model": model, **parameters}}}).fluid.rheology
    )


def test_defaults_build_the_right_laws():
    assert law_of("newtonian") == rheology.NewtonianViscosity(0.0035)
    # The study's Carreau parameters (docs/model.md §2).
    assert law_of("carreau") == rheology.CarreauViscosity(0.0456, 0.0032, 10.03, 0.344)
    assert law_of("carreau_yasuda") == rheology.CarreauYasudaViscosity(
        0.056, 0.00345, 1.902, 0.22, 1.25
    )
    assert law_of("cross") == rheology.CrossViscosity(0.0364, 0.0035, 0.38, 1.45)
    assert law_of("power_law") == rheology.PowerLawViscosity(0.017, 0.708, 0.0169)
    assert law_of("casson") == rheology.CassonViscosity(0.0035, 0.005, 100.0)


def test_carreau_values_and_limits():
    law = law_of("carreau")
    # μ(s) by hand at s = 1/λ: μ∞ + (μ0 − μ∞) 2^((n−1)/2)
    s = 1 / 10.03
    assert law.mu(s) == pytest.approx(
        0.0032 + (0.0456 - 0.0032) * 2 ** ((0.344 - 1) / 2), rel=1e-14
    )
    assert law.mu(0.0) == pytest.approx(0.0456, rel=1e-14)
    assert law.mu(1e9) == pytest.approx(0.0032, rel=1e-4)
    values = law.mu(np.logspace(-3, 4, 50))
    assert np.all(np.diff(values) < 0), "shear thinning: μ decreases with s"
    assert np.all(np.diff(values * np.logspace(-3, 4, 50)) > 0), "stress μ s increases with s"


def test_carreau_yasuda_with_a_2_is_carreau_and_cross_limits():
    s = np.logspace(-3, 4, 30)
    cy = law_of(
        "carreau_yasuda",
        mu_0=0.0456,
        mu_inf=0.0032,
        relaxation_time=10.03,
        power_index=0.344,
        yasuda_exponent=2.0,
    )
    assert np.allclose(cy.mu(s), law_of("carreau").mu(s), rtol=1e-14, atol=0)
    cross = law_of("cross")
    assert cross.mu(0.0) == pytest.approx(0.0364, rel=1e-14)
    assert cross.mu(1 / 0.38) == pytest.approx(0.0035 + (0.0364 - 0.0035) / 2, rel=1e-14)
    assert cross.mu(1e9) == pytest.approx(0.0035, rel=1e-6)


def test_power_law_regularisation():
    law = law_of("power_law")
    K, n, s0 = 0.017, 0.708, 0.0169
    # μ(0) = K s0^(n−1), about Johnston's cap of 0.056 Pa s
    assert law.mu(0.0) == pytest.approx(K * s0 ** (n - 1), rel=1e-14)
    assert law.mu(0.0) == pytest.approx(0.056, rel=2e-3)
    # Far above s0 the floor changes μ by (1 + s0²/s²)^((n−1)/2) − 1 ≈ (n − 1)/2 s0²/s²,
    # 4.2e-7 at s = 10 1/s
    s = np.array([10.0, 100.0, 1000.0])
    assert np.allclose(law.mu(s), K * s ** (n - 1), rtol=5e-7, atol=0)
    assert not np.allclose(law.mu(s[:1]), K * s[:1] ** (n - 1), rtol=3e-7, atol=0)


def test_casson_regularisation():
    law = law_of("casson")
    mu_c, tau_y, m = 0.0035, 0.005, 100.0
    # finite at rest: (√μc + √(τy m))²
    assert law.mu(0.0) == pytest.approx((np.sqrt(mu_c) + np.sqrt(tau_y * m)) ** 2, rel=1e-12)
    assert np.isfinite(law.mu(np.array([0.0, 1e-30, 1e-12]))).all()
    # continuous through the small-s branch of the numpy evaluation
    assert law.mu(1e-17) == pytest.approx(law.mu(0.0), rel=1e-7)
    # for m s ≫ 1 it is Casson's (√μc + √(τy/s))²: e^(−√(m s)) < 1e-13 at s = 1e3
    s = np.array([1e3, 1e4])
    assert np.allclose(law.mu(s), (np.sqrt(mu_c) + np.sqrt(tau_y / s)) ** 2, rtol=1e-12, atol=0)
    # the stress μ s → τy (the yield stress) as s → 0⁺ … only after the regularisation's scale
    # 1/m: check the Casson stress √τ = √τy + √(μc s) at s = 10 (e^(−√1000) negligible)
    assert np.sqrt(law.mu(10.0) * 10.0) == pytest.approx(
        np.sqrt(tau_y) + np.sqrt(mu_c * 10), rel=1e-12
    )


@pytest.mark.parametrize("model", MODELS)
def test_ufl_and_numpy_agree_and_shear_rate_of_simple_shear(model):
    """u = (γ y, 0) has s = γ exactly; the UFL law interpolated at s equals the numpy law."""
    law = law_of(model)
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)
    gamma = 37.5

    V = compat.function_space(mesh, "Lagrange", 2, (2,))
    u = dolfinx.fem.Function(V)
    u.interpolate(lambda x: np.vstack([gamma * x[1], 0 * x[0]]))
    s = support_run.shear_rate_field(u)
    assert np.allclose(s.x.array, gamma, rtol=1e-12, atol=0)
    mu = support_run.viscosity_field(u, law)
    assert np.allclose(
        mu.x.array, law.mu(np.sqrt(gamma**2 + rheology.SHEAR_RATE_EPSILON**2)), rtol=1e-12, atol=0
    )


def test_shear_rate_is_regularised_at_rest():
    """At u = 0 the shear rate is ε and its derivative (Newton's Jacobian) is finite."""
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_WORLD, 2, 2)

    V = compat.function_space(mesh, "Lagrange", 2, (2,))
    u = dolfinx.fem.Function(V)
    du = ufl.TestFunction(V)
    dx = ufl.Measure("dx", domain=mesh, metadata={"quadrature_degree": 2})
    s = rheology.shear_rate(u)
    value = mesh.comm.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(s * dx)))
    assert value == pytest.approx(rheology.SHEAR_RATE_EPSILON, rel=1e-12)
    jacobian = dolfinx.fem.assemble_vector(dolfinx.fem.form(ufl.derivative(s * dx, u, du)))
    assert np.isfinite(jacobian.array).all()


@pytest.mark.parametrize(
    "text,key,expected",
    [
        (
            "{model: carreau_yasuda, yasuda_exponent: 0}",
            "fluid.rheology.yasuda_exponent",
            "positive",
        ),
        ("{model: carreau_yasuda, mu_0: -1}", "fluid.rheology.mu_0", "positive"),
        ("{model: cross, exponent: -1.45}", "fluid.rheology.exponent", "positive"),
        ("{model: cross, relaxation_time: 0}", "fluid.rheology.relaxation_time", "positive"),
        ("{model: power_law, shear_rate_floor: 0}", "fluid.rheology.shear_rate_floor", "positive"),
        ("{model: power_law, consistency: -0.017}", "fluid.rheology.consistency", "positive"),
        ("{model: power_law, power_index: '0.7'}", "fluid.rheology.power_index", "a number"),
        ("{model: casson, yield_stress: -0.005}", "fluid.rheology.yield_stress", "positive"),
        ("{model: casson, regularization: 0}", "fluid.rheology.regularization", "positive"),
        (
            "{model: casson, viscosity: 0.0035, mu_0: 0.05}",
            "fluid.rheology.mu_0",
            "one of the keys",
        ),
        ("{model: bingham}", "fluid.rheology.model", "'casson'"),
    ],
)
def test_bad_rheology_is_refused_naming_the_key(text, key, expected):
    with pytest.raises(config.ConfigError) as error:
        config.from_dict(reader.parse_yaml(f"fluid: {{rheology: {text}}}"), "case.yaml")
    assert error.value.key == key and expected in str(error.value)
    assert str(error.value).startswith(f"case.yaml: {key}: expected")


def test_rheology_round_trips_through_yaml(tmp_path):
    for model in MODELS:
        case = config.from_dict({"fluid": {"rheology": {"model": model}}})
        path = tmp_path / f"{model}.yaml"
        config.dump(case, path)
        assert config.load(path) == case


def test_every_configured_model_has_a_law():
    """The physics' laws (fsi.physics.rheology.LAWS) know each ``fluid.rheology.model`` tag the
    schema admits, and no other, and each law takes exactly its section's parameters."""
    sections = {
        typing.get_args(typing.get_type_hints(option)["model"])[0]: option
        for option in typing.get_args(config.Rheology)
    }
    assert set(rheology.LAWS) == set(sections)
    for tag, section in sections.items():
        parameters = {f for f in section.__dataclass_fields__ if f != "model"}
        assert set(rheology.LAWS[tag].__dataclass_fields__) == parameters, tag
