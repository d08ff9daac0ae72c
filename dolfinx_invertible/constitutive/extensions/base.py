"""Extension descriptions: which extension, its threshold and stiffness."""

from __future__ import annotations

import numpy as np

from dolfinx_invertible.constitutive.models.base import Model
from dolfinx_invertible.constitutive.validation import Parameter, check_open_unit_interval

__all__ = ["Extension"]


class Extension:
    """Base of the invertible extensions: a threshold ``eps`` in (0, 1).

    Subclasses set ``extension_id``, the branch the compiled kernels take (checked by
    :mod:`~dolfinx_invertible.constitutive.extensions.registry`). ``eps`` may be a scalar
    ``dolfinx.fem.Constant``, read whenever the parameters are needed.
    """

    extension_id: int = -1
    has_energy: bool = True

    def __init__(self, eps):
        self._eps = Parameter("eps", eps, check_open_unit_interval)

    @property
    def eps(self) -> float:
        """Current ε."""
        return self._eps.value

    def parameters(self, model: Model) -> np.ndarray:
        """Parameters in the order the kernels read them after the model's: [ε, k]."""
        return np.array([self.eps, 0.0])

    def parameter_sources(self) -> dict:
        """{position in :meth:`parameters`: the Constant it is read from}."""
        return {} if self._eps.constant is None else {0: self._eps.constant}

    def derived_stiffness(self, model: Model) -> bool:
        """K follows the model's current μ, λ (C1 with ``k=None`` and a Constant μ or λ)."""
        return False

    def __repr__(self) -> str:
        return f"{type(self).__name__}(eps={self._eps!r})"
