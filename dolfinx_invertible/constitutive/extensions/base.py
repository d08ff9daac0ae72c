"""Extension descriptions: which extension, its threshold and stiffness."""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive.models.base import Model
from dolfinx_invertible.constitutive.validation import check_open_unit_interval

__all__ = ["Extension"]


class Extension:
    """Base of the invertible extensions: a threshold ``eps`` in (0, 1).

    :mod:`~dolfinx_invertible.constitutive.extensions.registry` gives each extension its
    ``extension_id``, the branch the compiled kernels take.
    """

    extension_id: int = -1
    has_energy: bool = True

    def __init__(self, eps: float):
        self.eps = check_open_unit_interval("eps", eps)

    def parameters(self, model: Model) -> np.ndarray:
        """Parameters in the order the kernels read them after the model's: [ε, k]."""
        return np.array([self.eps, 0.0])

    def __repr__(self) -> str:
        return f"{type(self).__name__}(eps={self.eps!r})"
