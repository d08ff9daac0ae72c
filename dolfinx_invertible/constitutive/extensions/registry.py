"""The registry of extensions: every extension once, by the ``extension_id`` each declares.

Id 0 is "no extension"; the registry checks at import that the extensions' ids are unique and
run 1, 2, ... without a gap. The compiled dispatch on these ids lives in
:func:`~dolfinx_invertible.constitutive.principal.principal_derivatives` (and the SVD-free
activity test in :mod:`~dolfinx_invertible.constitutive.invariants`); the tests check that every
registered extension is dispatched to its own module.
"""

from __future__ import annotations

from dolfinx_invertible.constitutive.extensions.base import Extension
from dolfinx_invertible.constitutive.extensions.c1 import C1
from dolfinx_invertible.constitutive.extensions.c2 import C2
from dolfinx_invertible.constitutive.extensions.ife import IFE
from dolfinx_invertible.constitutive.registry_ids import ordered_by_id

__all__ = ["C1_ID", "C2_ID", "EXTENSIONS", "IFE_ID", "NONE_ID"]

#: The id of "no extension".
NONE_ID = 0
#: Every extension in id order, ``None`` first: ``EXTENSIONS[extension.extension_id]``.
EXTENSIONS: tuple[type[Extension] | None, ...] = (
    None,
    *ordered_by_id((C1, C2, IFE), "extension_id", first=NONE_ID + 1),
)

# The ids as module constants, which the compiled dispatchers read as compile-time constants.
C1_ID = C1.extension_id
C2_ID = C2.extension_id
IFE_ID = IFE.extension_id
