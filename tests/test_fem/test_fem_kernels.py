"""The compiled assembly kernel (fem_reference._kernels) against the numpy reference path of HexAssembler:
internal force and tangent to round-off on random deformations for every material law and wall element
(mixed u–p and displacement), the tangent against central differences of the force, the force against
central differences of the energy, J <= 0 handling, and the checks in front of the kernel."""

import numpy as np
import pytest

from ancf.errors import ConfigError
from fem_reference import BellowsGeometry, MeshLevel
from fem_reference.assembly import HexAssembler
from fem_reference.material import Material
from fem_reference.mesh import build_mesh

TINY = MeshLevel(2, 1, 12, 1)

MATERIALS = {
    "decoupled NH": Material.neo_hookean(0.8e6, 40e6),
    "Mooney-Rivlin": Material.mooney_rivlin(0.3e6, 0.1e6, 50e6),
    "ex43 NH": Material.neo_hookean(0.8e6, 40e6, formulation="ex43"),
}
#: (material, wall element): the mixed element needs the decoupled volumetric energy
CASES = [(name, el) for name in MATERIALS for el in ("mixed", "displacement")
         if not (el == "mixed" and MATERIALS[name].formulation == "ex43")]


@pytest.fixture(scope="module")
def mesh():
    geo = BellowsGeometry(0.08, 4, 0.012, 0.018, 0.004, collar_length=0.004)
    return build_mesh(geo, TINY)


def _deformation(bm, seed, scale=0.2, noise=2e-5):
    """A large homogeneous deformation plus nodal noise (finite strain, every det F > 0)."""
    rng = np.random.default_rng(seed)
    G = scale * rng.standard_normal((3, 3))
    return G @ bm.mesh.doflocs + noise * rng.standard_normal((3, bm.n_nodes))


@pytest.mark.parametrize("name,element", CASES)
def test_kernel_equals_numpy_reference(mesh, name, element):
    mat = MATERIALS[name]
    ref = HexAssembler(mesh.mesh, mat, kernel="numpy", element=element)
    new = HexAssembler(mesh.mesh, mat, kernel="numba", element=element)
    assert np.array_equal(ref.pattern.indices, new.pattern.indices)
    for seed in range(3):
        U = _deformation(mesh, seed)
        f1, K1, j1 = ref.assemble(U)
        f2, K2, j2 = new.assemble(U)
        assert j1 > 0 and j2 == pytest.approx(j1, rel=1e-13)
        assert np.abs(f2 - f1).max() <= 1e-12 * np.abs(f1).max()
        # same CSR layout: compare the data arrays entry by entry
        assert np.array_equal(K1.indptr, K2.indptr) and np.array_equal(K1.indices, K2.indices)
        assert np.abs(K2.data - K1.data).max() <= 1e-12 * np.abs(K1.data).max()
        f3, K3, j3 = new.assemble(U, tangent=False)
        assert K3 is None and np.array_equal(f3, f2) and j3 == j2


@pytest.mark.parametrize("name,element", CASES)
def test_kernel_tangent_matches_central_fd_of_its_force(mesh, name, element):
    asm = HexAssembler(mesh.mesh, MATERIALS[name], kernel="numba", element=element)
    U = _deformation(mesh, 10)
    _, K, jmin = asm.assemble(U)
    assert jmin > 0
    rng = np.random.default_rng(11)
    d = rng.standard_normal(U.shape) * 1e-3
    h = 1e-6
    fd = (asm.assemble(U + h * d, False)[0] - asm.assemble(U - h * d, False)[0]) / (2 * h)
    an = K @ d.T.ravel()
    assert np.linalg.norm(fd - an) < 1e-7 * np.linalg.norm(an)
    # hyperelastic: the element matrices (so the assembled tangent) are symmetric
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    # and the force is the gradient of the stored energy (of the mixed element: with the projected term)
    f = asm.assemble(U, False)[0]
    de = (asm.energy(U + h * d) - asm.energy(U - h * d)) / (2 * h)
    assert de == pytest.approx(f @ d.T.ravel(), rel=1e-7)


def test_mixed_element_differs_from_the_displacement_element_only_in_its_volumetric_term(mesh):
    """Same deviatoric response: with κ small against μ the two elements nearly agree; a homogeneous
    deformation (J constant, so ΠJ = J) gives the same force; a bending-type field does not."""
    mat = MATERIALS["decoupled NH"]
    mix, dis = (HexAssembler(mesh.mesh, mat, element=el) for el in ("mixed", "displacement"))
    G = 0.1 * np.random.default_rng(7).standard_normal((3, 3))
    U = G @ mesh.mesh.doflocs
    f1, f2 = mix.assemble(U, False)[0], dis.assemble(U, False)[0]
    assert np.abs(f1 - f2).max() <= 1e-9 * np.abs(f2).max()
    X = mesh.mesh.doflocs
    Ub = np.stack([-0.5 * X[2] ** 2 * 20.0, 0 * X[0], X[0] * X[2] * 20.0])  # a varying J
    assert np.abs(mix.assemble(Ub, False)[0] - dis.assemble(Ub, False)[0]).max() > 1e-3 * np.abs(f2).max()
    assert mix.energy(Ub) < dis.energy(Ub)          # the projection removes part of the volumetric energy


def test_mixed_element_needs_the_decoupled_volumetric_law(mesh):
    with pytest.raises(ConfigError, match="element='displacement'"):
        HexAssembler(mesh.mesh, MATERIALS["ex43 NH"])
    with pytest.raises(ConfigError, match="wall element"):
        HexAssembler(mesh.mesh, MATERIALS["decoupled NH"], element="hybrid")


@pytest.mark.filterwarnings("ignore:All-NaN slice")  # the numpy path's nanmin on a NaN state
def test_kernel_flags_inverted_elements_like_numpy(mesh):
    mat = MATERIALS["decoupled NH"]
    ref = HexAssembler(mesh.mesh, mat, kernel="numpy")
    new = HexAssembler(mesh.mesh, mat)
    U = -2.0 * mesh.mesh.doflocs  # x = -X: det F = -1 everywhere
    for asm in (ref, new):
        _, K, jmin = asm.assemble(U)
        assert K is None and jmin <= 0
    Un = np.full_like(U, np.nan)
    for asm in (ref, new):
        _, K, jmin = asm.assemble(Un)
        assert K is None and jmin == -1.0


def test_kernel_inputs_are_checked(mesh):
    asm = HexAssembler(mesh.mesh, MATERIALS["decoupled NH"])
    with pytest.raises(ValueError):
        asm.assemble(np.zeros((3, mesh.n_nodes - 1)))
    with pytest.raises(ValueError):
        asm.assemble(np.zeros((mesh.n_nodes, 3)))
    with pytest.raises(ValueError):
        asm.assemble(np.zeros((3, mesh.n_nodes), complex))
    # integer and non-contiguous inputs are converted, not passed through
    U = np.asfortranarray(_deformation(mesh, 3))
    assert np.array_equal(asm.assemble(U)[0], asm.assemble(np.ascontiguousarray(U))[0])
    assert np.array_equal(asm.assemble(np.zeros((3, mesh.n_nodes), int))[0], np.zeros(3 * mesh.n_nodes))
    with pytest.raises(ConfigError):
        HexAssembler(mesh.mesh, MATERIALS["decoupled NH"], kernel="fortran")


def test_kernel_rejects_inconsistent_mesh_arrays(mesh):
    from fem_reference._kernels import HexKernel

    asm = HexAssembler(mesh.mesh, MATERIALS["decoupled NH"])
    k = asm._compiled
    args = dict(edofs=k.edofs, dphi=k.dphi, dx=k.dx, emap=k.emap, nnz=k.nnz, n_nodes=k.n_nodes,
                material=MATERIALS["decoupled NH"])
    HexKernel(**args)
    assert k.mixed and not HexKernel(**args).mixed       # without a pressure basis: the displacement element
    for key, bad in (("pressure_basis", k.pb[:, :, :3]), ("pressure_mass_inv", k.Mi * np.nan)):
        with pytest.raises(ValueError):
            HexKernel(**args, **{"pressure_basis": k.pb, "pressure_mass_inv": k.Mi, key: bad})
    with pytest.raises(ValueError):
        HexKernel(**args, pressure_basis=k.pb)
    for key, bad in (("edofs", k.edofs[:, :-1]), ("dphi", k.dphi[:, :, :2]), ("emap", k.emap[:-1]),
                     ("nnz", k.emap.max()), ("n_nodes", k.edofs.max()),
                     ("dx", np.where(k.dx > 0, np.nan, k.dx))):
        with pytest.raises(ValueError):
            HexKernel(**{**args, key: bad})


def test_pressure_kernel_equals_numpy_reference_and_fd(mesh):
    from fem_reference.assembly import PressureAssembler

    vol = HexAssembler(mesh.mesh, MATERIALS["decoupled NH"])
    ref = PressureAssembler(mesh.mesh, mesh.inner_facets(), vol.pattern, kernel="numpy")
    new = PressureAssembler(mesh.mesh, mesh.inner_facets(), vol.pattern)
    assert new._compiled is not None and ref._compiled is None
    p = 3e4
    for seed in range(2):
        U = _deformation(mesh, 20 + seed)
        f1, K1 = ref.assemble(U, p)
        f2, K2 = new.assemble(U, p)
        assert np.abs(f2 - f1).max() <= 1e-12 * np.abs(f1).max()
        assert np.array_equal(K1.indices, K2.indices)
        assert np.abs(K2.data - K1.data).max() <= 1e-12 * np.abs(K1.data).max()
        f3, K3 = new.assemble(U, p, tangent=False)
        assert K3 is None and np.array_equal(f3, f2)
    d = np.random.default_rng(5).standard_normal(U.shape) * 1e-3
    h = 1e-6
    fd = (new.assemble(U + h * d, p, False)[0] - new.assemble(U - h * d, p, False)[0]) / (2 * h)
    an = K2 @ d.T.ravel()
    assert np.linalg.norm(fd - an) < 1e-7 * np.linalg.norm(an)
    with pytest.raises(ValueError):
        new.assemble(np.zeros((3, 5)), p)


def test_pressure_in_reference_or_physical_coordinates(mesh, monkeypatch):
    """On affine elements (a box) the linear pressure in (ξ, η, ζ) and in (X, Y, Z) span the same space: the same
    force; on the curved bellows mesh they differ (docs/fem.md §3a)."""
    from skfem import MeshHex, MeshHex2

    mat = MATERIALS["decoupled NH"]
    box = MeshHex2.from_mesh(MeshHex.init_tensor(np.linspace(0, 0.02, 3), np.linspace(0, 0.01, 2),
                                                 np.linspace(0, 0.004, 2)))
    forces = {}
    for coords in ("reference", "physical"):
        monkeypatch.setattr(HexAssembler, "PRESSURE_COORDINATES", coords)
        for name, m in (("box", box), ("bellows", mesh.mesh)):
            X = m.doflocs
            U = np.stack([-40.0 * X[0] * X[2], 0.1 * X[1], 20.0 * X[0] ** 2])   # bending: J varies
            forces[coords, name] = HexAssembler(m, mat).assemble(U, False)[0]
    ref, phys = forces["reference", "box"], forces["physical", "box"]
    assert np.abs(ref - phys).max() <= 1e-9 * np.abs(ref).max()
    ref, phys = forces["reference", "bellows"], forces["physical", "bellows"]
    assert np.abs(ref - phys).max() > 1e-4 * np.abs(ref).max()
