"""The registry of extensions: every extension once, its id its position.

Position 0 is "no extension". The compiled dispatch on these ids lives in
:func:`~dolfinx_invertible.constitutive.principal.principal_derivatives` (and the SVD-free
activity test in :mod:`~dolfinx_invertible.constitutive.invariants`); the tests check that every
registered extension is dispatched to its own module.
"""

from __future__ import annotations

from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.extensions.c1 import C1
from dolfinx_invertible.constitutive.extensions.c2 import C2
from dolfinx_invertible.constitutive.extensions.ife import IFE

__all__ = ["C1_ID", "C2_ID", "EXTENSIONS", "IFE_ID", "NONE_ID"]

#: Every extension, in id order: an extension's id is its position here; 0 means none.
EXTENSIONS: tuple[type[Extension] | None, ...] = (None, C1, C2, IFE)
for _extension_id, _extension in enumerate(EXTENSIONS):
    if _extension is not None:
        _extension.extension_id = _extension_id

# The ids as module constants, which the compiled dispatchers read as compile-time constants.
NONE_ID = EXTENSIONS.index(None)
C1_ID = C1.extension_id
C2_ID = C2.extension_id
IFE_ID = IFE.extension_id
