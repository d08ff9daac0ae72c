"""Extension descriptions: which extension, its threshold and stiffness."""

from __future__ import annotations

import numpy as np

from dolfinx_invertible._validation import check_open_unit_interval
from dolfinx_invertible.models.base import Model

__all__ = ["NONE_ID", "C1_ID", "C2_ID", "IFE_ID", "Extension"]

# Branch ids the compiled kernels take.
NONE_ID = 0
C1_ID = 1
C2_ID = 2
IFE_ID = 3


class Extension:
    """Base of the invertible extensions: a threshold ``eps`` in (0, 1)."""

    extension_id: int = NONE_ID
    has_energy: bool = True

    def __init__(self, eps: float):
        self.eps = check_open_unit_interval("eps", eps)

    def parameters(self, model: Model) -> np.ndarray:
        """Parameters in the order the kernels read them after the model's: [ε, k]."""
        return np.array([self.eps, 0.0])

    def __repr__(self) -> str:
        return f"{type(self).__name__}(eps={self.eps!r})"
