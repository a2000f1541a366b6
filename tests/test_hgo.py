"""The Holzapfel–Gasser–Ogden law (fsi/physics/materials.py, ``HolzapfelGasserOgden``) against
its closed forms (fsi/benchmarks/hgo_tube.py): homogeneous deformations, Cauchy stress within
1e-8 relative; and the configuration's refusals of what the law cannot take.

The UFL law differentiates its energy (``2 ∂W/∂C`` by UFL); the closed forms write the stress
out from the invariants, so the two are independent. The law is evaluated on a one-cell mesh of
each rank's own (COMM_SELF): the numbers are the same on every rank.
"""

from __future__ import annotations

import math

from mpi4py import MPI

import dolfinx
import dolfinx.fem
import dolfinx.mesh
import numpy as np
import pytest
import ufl

from fsi import compat, config
from fsi.benchmarks.hgo_tube import HGOParameters, cauchy_stress, stress_differences
from fsi.config import reader
from fsi.physics import materials

# The media of a carotid as quoted from Holzapfel, Gasser & Ogden 2000 §5 (docs/arterial-wall.md)
# with a dispersion, and a nearly incompressible matrix (K = 1000 c).
MEDIA = HGOParameters(c=3.0e3, k1=2.3632e3, k2=0.8393, angle=29.0, dispersion=0.1, bulk_modulus=3e6)


def ufl_cauchy(F: np.ndarray, p: HGOParameters) -> np.ndarray:
    """The UFL law's Cauchy stress ``J⁻¹ F S Fᵀ`` at the constant deformation gradient F."""
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 1, 1)
    F_c = dolfinx.fem.Constant(mesh, np.asarray(F, dtype=float))
    beta = math.radians(p.angle)
    mu = p.c
    law = materials.HolzapfelGasserOgden(
        lmbda=p.bulk_modulus - 2 * mu / 3,
        mu=mu,
        k1=p.k1,
        k2=p.k2,
        dispersion=p.dispersion,
        fibres=materials.axisymmetric_fibres(math.sin(beta), math.cos(beta)),
    )
    sigma = materials.cauchy(law, ufl.as_tensor(F_c))
    expression = dolfinx.fem.Expression(sigma, np.array([[1 / 3, 1 / 3]]))
    return compat.eval_expression(expression, mesh, np.array([0])).reshape(3, 3)


def relative(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


# Frame (z, r, θ): F = diag(λ_z, λ_r, λ_θ) for the principal stretches.
HOMOGENEOUS = {
    "uniaxial along the axis": np.diag([1.3, 1 / math.sqrt(1.3) * 1.01, 1 / math.sqrt(1.3)]),
    "uniaxial around the hoop": np.diag([1 / math.sqrt(1.25), 1 / math.sqrt(1.25), 1.25]),
    "equibiaxial hoop-axial": np.diag([1.2, 1 / 1.2**2 * 0.995, 1.2]),
    "shear and stretch": np.array([[1.1, 0.2, 0.0], [0.05, 0.9, 0.0], [0.0, 0.0, 1.15]]),
}


@pytest.mark.parametrize("name", HOMOGENEOUS)
def test_the_cauchy_stress_matches_the_closed_form(name):
    """UFL's σ(F) against the written-out σ = J⁻¹ dev τ̄ + U'(J) I, fibres stretched
    (Ī₄ > 1 for both families), J ≠ 1 (the volumetric part too); with κ = 0 and κ = 0.1."""
    F = HOMOGENEOUS[name]
    for p in (MEDIA, HGOParameters(**{**MEDIA.__dict__, "dispersion": 0.0})):
        exact = cauchy_stress(F, p)
        assert relative(ufl_cauchy(F, p), exact) < 1e-8  # measured ≤ 2e-15


@pytest.mark.parametrize(
    "stretches",
    [(1.0, 1.4), (1.4, 1.0), (1.25, 1.25), (1.1, 1.5)],
    ids=["uniaxial hoop", "uniaxial axial", "equibiaxial", "biaxial"],
)
def test_incompressible_stretch_matches_the_reduced_energy(stretches):
    """At J = 1 the stress differences σ_θθ − σ_rr and σ_zz − σ_rr are the reduced energy's
    λ ∂Ŵ/∂λ (the tube solution's integrands); uniaxial and equibiaxial in the
    circumferential–axial plane. λ_r = 1/(λ_θ λ_z)."""
    lt, lz = stretches
    F = np.diag([lz, 1 / (lt * lz), lt])
    sigma = ufl_cauchy(F, MEDIA)
    hoop, axial = stress_differences(lt, lz, MEDIA)
    assert sigma[2, 2] - sigma[1, 1] == pytest.approx(hoop, rel=1e-8)
    assert sigma[0, 0] - sigma[1, 1] == pytest.approx(axial, rel=1e-8)


def test_fibres_carry_no_compression():
    """A deformation that shortens both families' mean directions (Ī₄ < 1) gives the matrix's
    stress alone: the same with k₁ = 2.36 kPa as with k₁ = 0."""
    F = np.diag([0.9, 1 / (0.9 * 0.95), 0.95])
    with_fibres = ufl_cauchy(F, MEDIA)
    without = ufl_cauchy(F, HGOParameters(**{**MEDIA.__dict__, "k1": 0.0}))
    np.testing.assert_allclose(with_fibres, without, rtol=1e-12, atol=1e-9)
    assert relative(with_fibres, cauchy_stress(F, MEDIA)) < 1e-8


# --------------------------------------------------------------------------------------------
# The configuration


def axisymmetric_case(**structure) -> dict:
    return {
        "geometry": {"kind": "tube", "axisymmetric": True},
        "structure": {"mode": "moving_wall", **structure},
    }


HGO_WALL = {"law": "hgo", "young_modulus": 9.0e3, "poisson_ratio": 0.499, "fibres": {}}


def test_an_axisymmetric_case_takes_an_hgo_wall():
    case = config.from_dict(axisymmetric_case(wall=HGO_WALL))
    assert case.structure.wall.law == "hgo"
    assert case.structure.wall.fibres == config.Fibres()


@pytest.mark.parametrize(
    "wall, key",
    [
        ({**HGO_WALL, "fibres": {"angle": 91}}, "structure.wall.fibres.angle"),
        ({**HGO_WALL, "fibres": {"angle": -1}}, "structure.wall.fibres.angle"),
        ({**HGO_WALL, "fibres": {"dispersion": 0.34}}, "structure.wall.fibres.dispersion"),
        ({**HGO_WALL, "fibres": {"dispersion": -0.01}}, "structure.wall.fibres.dispersion"),
        ({**HGO_WALL, "fibres": {"k1": -1.0}}, "structure.wall.fibres.k1"),
        ({**HGO_WALL, "fibres": {"k2": -0.5}}, "structure.wall.fibres.k2"),
        ({**HGO_WALL, "fibres": None}, "structure.wall.fibres"),
        ({"law": "svk", "fibres": {}}, "structure.wall.law"),
    ],
)
def test_bad_fibres_are_refused_naming_the_key(wall, key):
    with pytest.raises(reader.ConfigError) as error:
        config.from_dict(axisymmetric_case(wall=wall))
    assert error.value.key == key


def test_a_plane_model_refuses_the_hgo_law():
    """The fibres lie in the circumferential–axial plane: a plane section has no hoop
    direction, so the law is refused there (not given an in-plane meaning)."""
    data = axisymmetric_case(cap=HGO_WALL)
    data["geometry"] = {"kind": "stenosis"}
    with pytest.raises(reader.ConfigError) as error:
        config.from_dict(data)
    assert error.value.key == "structure.cap.law"
    assert "axisymmetric" in str(error.value)
