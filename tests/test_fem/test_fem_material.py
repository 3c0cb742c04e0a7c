"""Constitutive law: P = ∂ψ/∂F and A = ∂P/∂F against central finite differences; closed forms."""

import numpy as np
import pytest

from ancf.errors import ConfigError
from fem_reference import Material
from fem_reference.verification import uniaxial_block


@pytest.fixture(params=["decoupled", "ex43", "mooney_rivlin"])
def material(request):
    if request.param == "mooney_rivlin":
        return Material.mooney_rivlin(c10=0.3e6, c01=0.1e6, kappa=40e6)
    return Material.neo_hookean(mu=0.8e6, kappa=40e6, formulation=request.param)


def _random_F(n=5, seed=0):
    rng = np.random.default_rng(seed)
    F = np.eye(3)[:, :, None] + 0.25 * rng.standard_normal((3, 3, n))
    from fem_reference.material import _inv_det

    _, J = _inv_det(F)
    return F[:, :, J > 0.2]


def test_stress_is_energy_gradient(material):
    F = _random_F()
    P, _, _ = material.stress(F)
    h = 1e-6
    Pfd = np.zeros_like(P)
    for k in range(3):
        for L in range(3):
            Fp, Fm = F.copy(), F.copy()
            Fp[k, L] += h
            Fm[k, L] -= h
            Pfd[k, L] = (material.energy(Fp) - material.energy(Fm)) / (2 * h)
    assert np.abs(P - Pfd).max() < 1e-7 * np.abs(P).max()


def test_tangent_matches_finite_differences(material):
    F = _random_F(seed=1)
    _, A, _ = material.stress(F)
    h = 1e-7
    Afd = np.zeros_like(A)
    for k in range(3):
        for L in range(3):
            Fp, Fm = F.copy(), F.copy()
            Fp[k, L] += h
            Fm[k, L] -= h
            Afd[:, :, k, L] = (material.stress(Fp, False)[0] - material.stress(Fm, False)[0]) / (2 * h)
    assert np.abs(A - Afd).max() < 1e-6 * np.abs(A).max()


def test_small_strain_limit_is_linear_elasticity(material):
    _, A, J = material.stress(np.eye(3)[:, :, None])
    d = np.eye(3)
    lam, mu = material.lame_lambda, material.mu
    C = lam * np.einsum("ij,kl->ijkl", d, d) + mu * (np.einsum("ik,jl->ijkl", d, d) + np.einsum("il,jk->ijkl", d, d))
    assert np.allclose(A[..., 0], C, rtol=0, atol=1e-9 * lam)
    assert material.nu == pytest.approx(0.4901, abs=1e-3)


@pytest.mark.parametrize("stretch", [1.25, 1.5, 2.0])
def test_block_uniaxial_tension_exact(material, stretch):
    """FE block (Hex2, symmetry BCs) vs the exact homogeneous solution (docs/fem.md §6.1)."""
    fe = uniaxial_block(material, stretch, n=2,
                        element="mixed" if material.formulation == "decoupled" else "displacement")
    P11, l2 = material.uniaxial_stress(stretch)
    assert fe["P11"] == pytest.approx(P11, rel=1e-8)
    assert fe["lateral_stretch"] == pytest.approx(l2, rel=1e-8)
    # independent check of the closed form in the incompressible limit:
    # P = 2(λ − λ⁻²)(C10 + C01/λ)  (neo-Hookean: C01 = 0, 2 C10 = μ)
    c01 = material.c01
    c10 = material.mu / 2 - c01
    inc = 2 * (stretch - stretch ** -2) * (c10 + c01 / stretch)
    assert P11 == pytest.approx(inc, rel=0.08)
    # quadratic convergence of Newton: r_{k+1} <= C r_k^2 with a modest C
    h = np.array(fe["history"])
    assert h[-1] < 1e-10 * h[0]


def test_invalid_parameters():
    with pytest.raises(ConfigError):
        Material.neo_hookean(mu=-1.0, kappa=1e6)
    with pytest.raises(ConfigError):
        Material.neo_hookean(mu=1e6, kappa=0.1e6)
    m = Material.from_E_nu(2.4e6, 0.3)
    assert m.E == pytest.approx(2.4e6) and m.nu == pytest.approx(0.3)
