"""Model and extension ids as compile-time literals: each compiled chain holds one material.

The compiled functions take the model id and the extension id as arguments, and the functions
that branch on them (the dispatchers of :mod:`.models.registry` and :mod:`.principal`) are
``numba.extending.overload`` s that resolve the branch while typing, from the id's literal value.
So a kernel compiled for Neo-Hookean + C2 contains Neo-Hookean and C2 and nothing else: the cold
compile pays for one material's chain, not for six models × four extensions behind a run-time
switch. numba types every function of the chain once per (model, extension) pair it is called
with; parameters stay run-time values, so a parameter sweep never recompiles.

An id known only at run time (a Python ``int`` passed to a compiled batch loop, say) is turned
into a literal by ``numba.literally``: the outermost compiled function is recompiled for that
value (and cached on disk per value).
"""

from __future__ import annotations

import inspect

import numba
from numba.core import types

__all__ = ["force_literal", "literal_id"]


def literal_id(selector) -> int | None:
    """Return the compile-time value of an id argument's numba type, None if only run-time."""
    if isinstance(selector, types.IntegerLiteral):
        return int(selector.literal_value)
    return None


def force_literal(stub):
    """Overload implementation for a run-time id (the first argument of ``stub``).

    ``numba.literally`` makes the dispatcher that received the id recompile with it as a
    literal; the implementation never runs. It repeats the stub's argument names, as numba
    requires of an overload's implementation.
    """
    names = inspect.getfullargspec(stub).args
    source = f"def force({', '.join(names)}):\n    numba.literally({names[0]})\n"
    namespace = {"numba": numba}
    exec(source, namespace)  # noqa: S102 - a fixed template over the stub's own argument names
    return namespace["force"]
