"""DOLFINx's own route: the plain Neo-Hookean energy written in UFL and compiled by FFCx.

The baseline every comparison needs (reports, benchmarks, the stability study): the same
energy as :class:`~dolfinx_invertible.NeoHookean` without extension,

    Ψ = μ/2 (tr C − d) − μ ln J + λ/2 (ln J)²,

as a UFL form, its residual and tangent by ``ufl.derivative``, assembled by DOLFINx's generated
kernels. :class:`UFLNeoHookeanForms` has the interface of
:class:`~dolfinx_invertible.fem.forms.HyperelasticForms`, so a problem can take either; it has
only the exact tangent (no projection) and no SVD-path counts.
"""

from __future__ import annotations

import dolfinx
import ufl

from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive.material import Material
from dolfinx_invertible.constitutive.models import NeoHookean

__all__ = ["UFLNeoHookeanForms", "ufl_neo_hookean_energy"]


def ufl_neo_hookean_energy(u, mu, lam, quadrature_degree: int):
    """Return ∫ μ/2 (tr C − d) − μ ln J + λ/2 (ln J)² dX as a UFL form in ``u``.

    ``mu`` and ``lam`` may be numbers or DOLFINx Constants.
    """
    dimension = len(u)
    gradient = ufl.Identity(dimension) + ufl.grad(u)
    log_volume = ufl.ln(ufl.det(gradient))
    psi = (
        mu / 2 * (ufl.tr(gradient.T * gradient) - dimension)
        - mu * log_volume
        + lam / 2 * log_volume**2
    )
    return psi * ufl.dx(metadata={"quadrature_degree": quadrature_degree})


class UFLNeoHookeanForms:
    """Energy, residual and tangent forms of plain Neo-Hookean through UFL and FFCx.

    Parameters
    ----------
    u
        Displacement, a vector Lagrange Function.
    material
        A :class:`~dolfinx_invertible.Material` of :class:`~dolfinx_invertible.NeoHookean`
        without extension (UFL has no SVD, so no extension).
    quadrature_degree
        Degree of the cell rule; default that of the kernels' forms.
    """

    def __init__(self, u, material: Material, *, quadrature_degree: int | None = None):
        if not isinstance(material.model, NeoHookean) or material.extension is not None:
            raise ValueError(
                "DOLFINx's own route (UFL) is plain Neo-Hookean only, without extension; got "
                f"{material!r}"
            )
        from dolfinx_invertible.fem.forms import default_quadrature_degree

        if quadrature_degree is None:
            quadrature_degree = default_quadrature_degree(
                _compat.element_degree(u.function_space), u.function_space.mesh.topology.cell_type
            )
        self.u = u
        self.material = material
        self.quadrature_degree = int(quadrature_degree)
        self.project = False
        energy = ufl_neo_hookean_energy(
            u, material.model.mu, material.model.lam, self.quadrature_degree
        )
        residual = ufl.derivative(energy, u)
        self.energy = dolfinx.fem.form(energy)
        self.residual = dolfinx.fem.form(residual)
        self.jacobian = dolfinx.fem.form(ufl.derivative(residual, u))

    def path_counts(self) -> dict[str, tuple[int, int]]:
        """Return no counts: FFCx's kernels have no SVD path."""
        return {}

    def reset_path_counts(self) -> None:
        """Do nothing: there are no counters."""

    def set_projection(self, project: bool) -> None:
        """Refuse the projected tangent, which UFL's route does not have."""
        if project:
            raise ValueError("DOLFINx's own route (UFL) has only the exact tangent")
