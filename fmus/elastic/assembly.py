"""Finite-element matrices of a linear isotropic elastic body (pure functions).

2-D meshes are plane stress with a thickness, 3-D meshes are solids. Units: SI, so
K is in N/m, M in kg, forces in N, displacements in m, stresses in Pa.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import Basis, BilinearForm, CellBasis, ElementVector, Mesh, asm
from skfem.helpers import dot
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


STEEL = Material(youngs_modulus=210e9, poisson_ratio=0.3, density=7850.0)


@BilinearForm
def _mass_form(u, v, w):
    return dot(u, v)


def vector_basis(mesh: Mesh) -> Basis:
    """Vector-valued first-order basis (dofs ``basis.nodal_dofs[c, node]``)."""
    check_mesh(mesh)
    return Basis(mesh, ElementVector(ELEMENTS[type(mesh).__name__]()))


def stiffness_matrix(basis: Basis, material: Material, thickness: float = 1.0) -> sp.csr_matrix:
    """Stiffness K (N/m) on all dofs; 2-D bodies are scaled by ``thickness`` (m)."""
    lam, mu = material.lame(basis.mesh.dim())
    scale = thickness if basis.mesh.dim() == 2 else 1.0
    return (scale * asm(linear_elasticity(lam, mu), basis)).tocsr()


def mass_matrix(basis: Basis, material: Material, thickness: float = 1.0,
                lumped: bool = False) -> sp.csr_matrix:
    """Consistent mass M (kg), or its row-sum lumped diagonal if ``lumped``."""
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
