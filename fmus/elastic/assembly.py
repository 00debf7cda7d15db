"""Finite-element matrices of a linear isotropic elastic body (pure functions).

2-D meshes are plane stress with a thickness, 3-D meshes are solids. Units: SI, so
K is in N/m, M in kg, forces in N, displacements in m, stresses in Pa.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import Basis, BilinearForm, CellBasis, ElementVector, Mesh, asm
from skfem.helpers import ddot, div, dot, sym_grad
from skfem.models.elasticity import linear_elasticity

from .geometry import ELEMENTS, check_mesh


@dataclass(frozen=True)
class Material:
    """Linear isotropic material: Young's modulus (Pa), Poisson ratio (-), density (kg/m^3)."""

    youngs_modulus: float
    poisson_ratio: float
    density: float

    def __post_init__(self):
        if not (self.youngs_modulus > 0 and self.density > 0
                and -1.0 < self.poisson_ratio < 0.5):
            raise ValueError(f"invalid material {self}")

    def lame(self, dim: int) -> tuple[float, float]:
        """Lame parameters (Pa): plane stress for ``dim == 2``, 3-D otherwise."""
        E, nu = self.youngs_modulus, self.poisson_ratio
        mu = E / (2.0 * (1.0 + nu))
        if dim == 2:  # plane stress: lambda* = 2 lambda mu / (lambda + 2 mu)
            return E * nu / (1.0 - nu ** 2), mu
        return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), mu


#: The linear scalar elements (order 1).
LINEAR = {elements[1] for elements in ELEMENTS.values()}

STEEL = Material(youngs_modulus=210e9, poisson_ratio=0.3, density=7850.0)


@BilinearForm
def _mass_form(u, v, w):
    return dot(u, v)


def vector_basis(mesh: Mesh, order: int = 1) -> Basis:
    """Vector-valued basis of element order 1 (linear) or 2 (quadratic, see ELEMENTS)."""
    check_mesh(mesh)
    if order not in (1, 2):
        raise ValueError(f"element order must be 1 or 2, got {order}")
    element = ElementVector(ELEMENTS[type(mesh).__name__][order]())
    if order == 1:
        return Basis(mesh, element)
    # 3-point Gauss per direction: exact for the mass and stiffness of straight-sided
    # quadratic elements (polynomials of degree 4); skfem's default uses 5 points,
    # which makes assembling 20-node hexahedra four times slower for nothing
    return Basis(mesh, element, intorder=4)


#: matrices assembled in this process, by everything they are made of (the mesh's and
#: the quadrature's arrays as bytes, the element, the material, the thickness): a body
#: instantiated again on the same mesh in this process (the next run of a scene, a
#: sweep's next point) is not assembled again (over a second for four_post's plate).  Written here because functools' caches cannot key on arrays; kept small and
#: for matrices of at most _KEPT_NONZEROS entries, as the bodies hold only their reduced
#: matrices.
_ASSEMBLED: dict[tuple, sp.csr_matrix] = {}
_KEPT, _KEPT_NONZEROS = 8, 2_000_000
_ASSEMBLED_LOCK = threading.Lock()


def _key(kind: str, basis: Basis, *more) -> tuple:
    mesh = basis.mesh
    return (kind, type(mesh).__name__, mesh.p.shape, mesh.p.tobytes(), mesh.t.shape,
            mesh.t.tobytes(), type(basis.elem).__name__, type(basis.elem.elem).__name__,
            basis.X.tobytes(), basis.W.tobytes(), *more)


def _assembled(key: tuple, assemble) -> sp.csr_matrix:
    """The matrix ``assemble()`` makes, assembled once per ``key`` (see _ASSEMBLED); a
    copy, so that no caller changes the one kept."""
    with _ASSEMBLED_LOCK:
        found = _ASSEMBLED.get(key)
    if found is None:
        found = assemble()
        if found.nnz <= _KEPT_NONZEROS:
            with _ASSEMBLED_LOCK:
                if len(_ASSEMBLED) >= _KEPT:
                    del _ASSEMBLED[next(iter(_ASSEMBLED))]
                _ASSEMBLED[key] = found
    return found.copy()


def stiffness_matrix(basis: Basis, material: Material, thickness: float = 1.0) -> sp.csr_matrix:
    """Stiffness K (N/m) on all dofs; 2-D bodies are scaled by ``thickness`` (m)."""
    return _assembled(_key("K", basis, material, thickness),
                      lambda: _stiffness_matrix(basis, material, thickness))


def _stiffness_matrix(basis: Basis, material: Material, thickness: float) -> sp.csr_matrix:
    lam, mu = material.lame(basis.mesh.dim())
    scale = thickness if basis.mesh.dim() == 2 else 1.0

    if type(basis.elem.elem) in LINEAR:  # skfem's own form
        return (scale * asm(linear_elasticity(lam, mu), basis)).tocsr()

    # sigma(u) : eps(v) = lam div u div v + 2 mu eps(u) : eps(v): linear_elasticity's
    # form without building sigma per dof pair (seconds for 20-node hexahedra)
    @BilinearForm
    def elasticity(u, v, w):
        return lam * div(u) * div(v) + 2.0 * mu * ddot(sym_grad(u), sym_grad(v))
    return (scale * asm(elasticity, basis)).tocsr()


def mass_matrix(basis: Basis, material: Material, thickness: float = 1.0,
                lumped: bool = False) -> sp.csr_matrix:
    """Consistent mass M (kg), or its row-sum lumped diagonal if ``lumped``."""
    return _assembled(_key("M", basis, material, thickness, lumped),
                      lambda: _mass_matrix(basis, material, thickness, lumped))


def _mass_matrix(basis: Basis, material: Material, thickness: float,
                 lumped: bool) -> sp.csr_matrix:
    scale = material.density * (thickness if basis.mesh.dim() == 2 else 1.0)
    mass = scale * asm(_mass_form, basis)
    if lumped:  # row sums are positive for linear elements, and keep the total mass
        return sp.diags(np.asarray(mass.sum(axis=1)).ravel()).tocsr()
    return mass.tocsr()


def von_mises(basis: Basis, material: Material, displacement: np.ndarray,
              element: int) -> float:
    """Von Mises stress (Pa) averaged over the quadrature points of one element.

    ``displacement`` is the full nodal displacement vector (m) of ``basis``.
    """
    local = CellBasis(basis.mesh, basis.elem, elements=np.array([element]))
    grad = local.interpolate(displacement).grad  # shape (dim, dim, 1, nqp)
    strain = 0.5 * (grad + np.swapaxes(grad, 0, 1))
    lam, mu = material.lame(basis.mesh.dim())
    dim = basis.mesh.dim()
    trace = np.einsum("ii...->...", strain)
    stress = 2.0 * mu * strain + lam * trace * np.eye(dim)[:, :, None, None]
    stress = stress.mean(axis=(2, 3))
    deviator = stress - np.trace(stress) / 3.0 * np.eye(dim)
    if dim == 2:  # plane stress: sigma_zz = 0 also enters the deviator
        szz = -np.trace(stress) / 3.0
        return float(np.sqrt(1.5 * (np.sum(deviator ** 2) + szz ** 2)))
    return float(np.sqrt(1.5 * np.sum(deviator ** 2)))
