"""Input checks shared by the public API: clear errors that name the offending parameter."""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = [
    "Parameter",
    "as_deformation_gradients",
    "as_singular_values",
    "check_positive",
    "check_open_unit_interval",
]

_MAX_REPORTED = 5


def check_positive(name: str, value: float) -> float:
    """Return ``value`` as float, or raise ``ValueError`` naming ``name`` unless finite and > 0."""
    value = float(value)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return value


def check_open_unit_interval(name: str, value: float) -> float:
    """Return ``value`` as float, or raise ``ValueError`` naming ``name`` unless in (0, 1)."""
    value = float(value)
    if not (0.0 < value < 1.0):
        raise ValueError(f"{name} must lie in the open interval (0, 1), got {value!r}")
    return value


def is_scalar_constant(value) -> bool:
    """Tell a scalar DOLFINx ``Constant``, recognised without importing DOLFINx (duck typing).

    Anything with a ``value`` attribute that is a NumPy array of exactly one entry and is not
    itself a number or an array.
    """
    if isinstance(value, (numbers.Number, np.ndarray)):
        return False
    try:
        current = getattr(value, "value", None)
    except Exception:  # noqa: BLE001 - an object whose attribute access fails is no Constant
        return False
    return isinstance(current, np.ndarray) and current.size == 1


class Parameter:
    """A material parameter: a real number, or a scalar DOLFINx Constant read when needed.

    The value is checked by ``check`` (a function of the name and the float value) when it is
    read, so a Constant set to a bad value is reported by the next evaluation. Anything else (a
    UFL expression, an array, a string) is refused at once with a ``TypeError``: calling
    ``float()`` on a UFL expression can recurse for a very long time.
    """

    def __init__(self, name: str, value, check):
        self.name = name
        self.check = check
        if is_scalar_constant(value):
            self.constant = value
            self.fixed = None
        elif isinstance(value, numbers.Real) and not isinstance(value, bool):
            self.constant = None
            self.fixed = float(value)
        else:
            raise TypeError(
                f"{name} must be a real number or a scalar dolfinx.fem.Constant (e.g. "
                f"fem.Constant(mesh, 3846.0)), got {type(value).__name__}: UFL expressions and "
                "arrays are not accepted"
            )
        self.value  # noqa: B018 - checks the value now

    @property
    def value(self) -> float:
        """The current value (a Constant's ``value`` read now), checked."""
        if self.constant is None:
            raw = self.fixed
        else:
            raw = float(np.asarray(self.constant.value, dtype=np.float64).reshape(-1)[0])
        return self.check(self.name, raw)

    def __repr__(self) -> str:
        return repr(self.fixed) if self.constant is None else f"Constant({self.value!r})"


def _check_finite(name: str, array: np.ndarray) -> None:
    bad = np.argwhere(~np.isfinite(array))
    if len(bad):
        shown = ", ".join(str(tuple(int(i) for i in index)) for index in bad[:_MAX_REPORTED])
        more = f" and {len(bad) - _MAX_REPORTED} more" if len(bad) > _MAX_REPORTED else ""
        raise ValueError(f"{name} has {len(bad)} non-finite entries at indices {shown}{more}")


def as_deformation_gradients(F) -> tuple[np.ndarray, bool]:
    """Validate deformation gradients and return them as a C-contiguous ``(n, d, d)`` batch.

    Returns the batch and whether a single ``(d, d)`` matrix was given.
    """
    array = np.asarray(F, dtype=np.float64)
    single = array.ndim == 2
    if single:
        array = array[np.newaxis]
    if array.ndim != 3 or array.shape[1] != array.shape[2] or array.shape[1] not in (2, 3):
        raise ValueError(
            f"F must have shape (n, d, d) or (d, d) with d = 2 or 3, got shape {np.shape(F)}"
        )
    _check_finite("F", array)
    return np.ascontiguousarray(array), single


def as_singular_values(sigma) -> tuple[np.ndarray, bool]:
    """Validate signed singular values and return them as a C-contiguous ``(n, d)`` batch."""
    array = np.asarray(sigma, dtype=np.float64)
    single = array.ndim == 1
    if single:
        array = array[np.newaxis]
    if array.ndim != 2 or array.shape[1] not in (2, 3):
        raise ValueError(
            f"sigma must have shape (n, d) or (d,) with d = 2 or 3, got shape {np.shape(sigma)}"
        )
    _check_finite("sigma", array)
    return np.ascontiguousarray(array), single
