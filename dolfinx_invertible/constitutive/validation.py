"""Input checks shared by the public API: clear errors that name the offending parameter."""

from __future__ import annotations

import math

import numpy as np

__all__ = [
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
