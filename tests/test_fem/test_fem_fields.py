"""Stress and stretch fields of the FEM's VTU output (fem_reference.fields, BellowsResult.save_vtu): closed forms of
homogeneous deformations imposed on the coarsest mesh (neo-Hookean with the mixed u–p element, Mooney–Rivlin,
the ex43 neo-Hookean with the displacement element), zero load, and a solved pressure case read back with meshio
and pyvista."""

import numpy as np
import pytest
from scipy.optimize import brentq

from ancf.errors import InputError
from fem_reference import BellowsModel, MeshLevel, presets
from fem_reference.assembly import HexAssembler
from fem_reference.fields import cell_fields
from fem_reference.material import Material

TINY = MeshLevel(2, 1, 12, 1)


@pytest.fixture(scope="module")
def model():
    return BellowsModel(presets.paper_bellows(), presets.paper_material(), TINY)


def _rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _impose(bmesh, F):
    """Nodal displacements of the homogeneous deformation x = F X, shape (3, n_nodes)."""
    return (np.asarray(F) - np.eye(3)) @ bmesh.X


def _dev(A):
    return A - np.trace(A) / 3 * np.eye(3)


def sigma_decoupled_nh(mu, kappa, F):
    """Decoupled neo-Hookean Cauchy stress: μ J^{-5/3} dev(b) + κ (J − 1) I."""
    J = np.linalg.det(F)
    return mu * J ** (-5 / 3) * _dev(F @ F.T) + kappa * (J - 1) * np.eye(3)


def sigma_decoupled_mr(c10, c01, kappa, F):
    """Decoupled Mooney–Rivlin (Holzapfel eq. 6.105 with ψ₁ = C10, ψ₂ = C01):
    (2/J) dev[(C10 + C01 Ī₁) b̄ − C01 b̄²] + κ (J − 1) I, with b̄ = J^{-2/3} b."""
    J = np.linalg.det(F)
    bb = J ** (-2 / 3) * F @ F.T
    return 2 / J * _dev((c10 + c01 * np.trace(bb)) * bb - c01 * bb @ bb) + kappa * (J - 1) * np.eye(3)


def sigma_ex43(mu, lam, F):
    """Compressible neo-Hookean of scikit-fem ex43: (μ/J)(b − I) + (λ ln J / J) I."""
    J = np.linalg.det(F)
    return mu / J * (F @ F.T - np.eye(3)) + lam * np.log(J) / J * np.eye(3)


def uniaxial(sigma_of_F, l1):
    """F = diag(λ₁, λ₂, λ₂) with the lateral stretch λ₂ of a uniaxial stress state (σ₂₂ = 0), by bisection on the
    closed form."""
    l2 = brentq(lambda x: sigma_of_F(np.diag([l1, x, x]))[1, 1], 0.2, 5.0, xtol=1e-15, rtol=1e-15)
    return np.diag([l1, l2, l2]), l2


def _check_fields(f, sigma, stretches, J):
    ne = f["von_mises_Pa"].shape[0]
    scale = np.abs(sigma).max()
    assert f["cauchy_stress_Pa"].shape == (ne, 3, 3)
    assert np.abs(f["cauchy_stress_Pa"] - sigma).max() < 1e-8 * scale
    s = _dev(sigma)
    assert np.allclose(f["von_mises_Pa"], np.sqrt(1.5 * np.sum(s * s)), rtol=1e-8)
    assert np.allclose(f["pressure_Pa"], -np.trace(sigma) / 3, rtol=0, atol=1e-8 * scale)
    assert np.allclose(f["principal_stretches"], np.sort(stretches)[::-1], rtol=1e-10)
    assert np.allclose(f["volume_ratio"], J, rtol=1e-10)


@pytest.mark.parametrize("l1, angle", [(1.3, 0.0), (0.8, 0.0), (1.5, 0.7)])
def test_uniaxial_neo_hookean_mixed_element(model, l1, angle):
    """x = Q diag(λ₁, λ₂, λ₂) X on the bellows mesh (mixed u–p element, whose pressure field reproduces a
    constant κ(J − 1) exactly): Cauchy stress Q σ₀ Qᵀ with σ₀ = diag(σ₁₁, 0, 0), von Mises |σ₁₁|, principal
    stretches (λ₁, λ₂, λ₂), pressure −σ₁₁/3."""
    mat = model.material
    assert model.element == "mixed" and mat.formulation == "decoupled" and mat.c01 == 0
    sig = lambda F: sigma_decoupled_nh(mat.mu, mat.kappa, F)
    D, l2 = uniaxial(sig, l1)
    Q = _rotation([1.0, -2.0, 0.5], angle)
    F = Q @ D
    sigma = sig(F)
    s11 = sig(D)[0, 0]
    assert np.allclose(sigma, s11 * np.outer(Q[:, 0], Q[:, 0]), atol=1e-9 * abs(s11))  # uniaxial along Q e₁
    f = cell_fields(model.asm, _impose(model.bmesh, F))
    _check_fields(f, sigma, [l1, l2, l2], l1 * l2 * l2)
    assert np.allclose(f["von_mises_Pa"], abs(s11), rtol=1e-8)
    # the incompressible limit as a sanity check of the closed form's magnitude: σ₁₁ ≈ μ(λ² − 1/λ)
    assert s11 == pytest.approx(mat.mu * (l1 ** 2 - 1 / l1), rel=0.05)


@pytest.mark.parametrize("element", ["mixed", "displacement"])
def test_mooney_rivlin_general_homogeneous_state(model, element):
    """A general (shear + stretch, volume-changing) homogeneous F, decoupled Mooney–Rivlin."""
    c10, c01, kappa = 0.3e6, 0.1e6, 20e6
    asm = HexAssembler(model.bmesh.mesh, Material.mooney_rivlin(c10, c01, kappa), kernel="numpy", element=element)
    F = np.array([[1.2, 0.3, 0.0], [0.05, 0.9, 0.1], [0.0, -0.2, 1.05]])
    ev = np.linalg.eigvalsh(F @ F.T)
    _check_fields(cell_fields(asm, _impose(model.bmesh, F)), sigma_decoupled_mr(c10, c01, kappa, F),
                  np.sqrt(ev), np.linalg.det(F))


def test_ex43_neo_hookean_displacement_element(model):
    mat = Material.neo_hookean(0.8e6, 8e6, formulation="ex43")
    asm = HexAssembler(model.bmesh.mesh, mat, kernel="numpy", element="displacement")
    F = _rotation([0, 0, 1], 0.4) @ np.diag([1.1, 0.95, 1.2])
    _check_fields(cell_fields(asm, _impose(model.bmesh, F)), sigma_ex43(mat.mu, mat.lame_lambda, F),
                  [1.1, 0.95, 1.2], 1.1 * 0.95 * 1.2)


def test_inverted_element_is_rejected(model):
    with pytest.raises(InputError, match="invert"):
        cell_fields(model.asm, _impose(model.bmesh, np.diag([1.0, 1.0, -1.0])))


def _read_both(path):
    import meshio
    import pyvista as pv

    return meshio.read(path), pv.read(path)


def test_zero_load_vtu_has_zero_stress_and_unit_stretches(model, tmp_path):
    res = model.solve(check_stability=False)
    m, g = _read_both(res.save_vtu(tmp_path / "zero.vtu"))
    ne = model.bmesh.n_elements
    for k, shape in (("cauchy_stress_Pa", (ne, 9)), ("von_mises_Pa", (ne,)), ("pressure_Pa", (ne,)),
                     ("principal_stretches", (ne, 3)), ("volume_ratio", (ne,))):
        assert m.cell_data[k][0].shape == shape and g.cell_data[k].shape == shape, k
    for k in ("cauchy_stress_Pa", "von_mises_Pa", "pressure_Pa"):
        assert np.abs(g.cell_data[k]).max() < 1e-6, k        # Pa, of a shear modulus 0.8 MPa
    assert np.allclose(g.cell_data["principal_stretches"], 1.0, rtol=0, atol=1e-12)
    assert np.all(g.point_data["chamber_pressure_Pa"] == 0.0)


def test_pressurised_vtu_round_trip(model, tmp_path):
    """A solved 20 kPa case: the file holds the fields of cell_fields (meshio and pyvista agree), the cells are
    in the mesh's element order (the stress of a homogeneous state would not show it: here each cell differs),
    the chamber pressure sits on the whole inner surface, and the mixed element's pressure field is −p_h."""
    p = 20e3
    res = model.solve(pressure=p, check_stability=False)
    m, g = _read_both(res.save_vtu(tmp_path / "p.vtu"))
    f = cell_fields(model.asm, res.state.U)
    assert np.allclose(m.cell_data["cauchy_stress_Pa"][0], f["cauchy_stress_Pa"].reshape(-1, 9), rtol=1e-12)
    assert np.allclose(g.cell_data["von_mises_Pa"], f["von_mises_Pa"], rtol=1e-12)
    assert g.cell_data["cauchy_stress_Pa"].shape[1] == 9            # a tensor for ParaView
    # cell order: each cell's centroid (from the file's nodes) is the centroid of the same element of the model
    centres_file = m.points[m.cells[0].data].mean(axis=1)
    centres_model = model.bmesh.X[:, model.asm.edofs].mean(axis=1).T
    assert np.allclose(centres_file, centres_model, rtol=0, atol=1e-12)
    inner = model.bmesh.lattice[1] == 0                             # τ = −t/2: the pressurised wall surface
    assert np.array_equal(g.point_data["chamber_pressure_Pa"] == p, inner)
    assert np.allclose(g.point_data["displacement"], res.state.U.T)
    # the u–p pressure field p_h = κ Π(J − 1), averaged over the deformed element, is minus the hydrostatic pressure
    F = model.asm.deformation_gradient(res.state.U)
    J = np.linalg.det(np.moveaxis(F, (0, 1), (-2, -1)))
    ph = model.material.kappa * model.asm._projected(J - 1.0)
    w = J * model.asm.dx
    assert np.allclose(f["pressure_Pa"], -(ph * w).sum(1) / w.sum(1), rtol=1e-9, atol=1e-9 * p)
    # plausibility: the thin wall's stresses are a multiple of the chamber pressure (hoop ≈ p R / t)
    assert 1.0 * p < f["von_mises_Pa"].max() < 100 * p
    assert np.all(f["principal_stretches"][:, 0] >= f["principal_stretches"][:, 1])
