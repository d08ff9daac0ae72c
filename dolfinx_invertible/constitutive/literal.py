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

The dimension ``d`` is a literal in the same way (:func:`dispatch_on_dimension`): a 3D kernel
compiles the 3D functions of its chain and not their 2D twins. numba 0.56 prunes ``if d == 3:``
only on a closure's constant, not on a literal argument, so the functions that pick a twin are
overloads too.
"""

from __future__ import annotations

import functools
import inspect

import numba
import numpy as np
from numba.core import types

from dolfinx_invertible.constitutive.compiled import compiled_overload

__all__ = ["dispatch_on_dimension", "force_literal", "literal_id", "run_time_integers"]


def run_time_integers(*values: int) -> tuple:
    """Return the integers as NumPy scalars, which numba types as run-time ``int64``.

    A Python ``int`` constant passed to a compiled function is typed as a literal, so numba
    compiles the callee (and its whole chain) once per value. Integers that only index or select
    at run time (pair indices, derivative orders, counter fields) are passed as these instead.
    """
    return tuple(np.array(values, dtype=np.int64))


def literal_id(selector) -> int | None:
    """Return the compile-time value of an id argument's numba type, None if only run-time."""
    if isinstance(selector, types.IntegerLiteral):
        return int(selector.literal_value)
    return None


def force_literal(stub, name=None):
    """Overload implementation for a run-time id (argument ``name``, default the first of ``stub``).

    ``numba.literally`` makes the dispatcher that received the id recompile with it as a
    literal; the implementation never runs. It repeats the stub's argument names, as numba
    requires of an overload's implementation.
    """
    names = inspect.getfullargspec(stub).args
    source = f"def force({', '.join(names)}):\n    numba.literally({name or names[0]})\n"
    namespace = {"numba": numba}
    exec(source, namespace)  # noqa: S102 - a fixed template over the stub's own argument names
    return namespace["force"]


def dispatch_on_dimension(stub, twins):
    """Compile a call of ``stub`` with a literal argument ``d`` as a call of ``twins[d]``.

    ``twins`` maps each dimension to a compiled function whose arguments are some of those of
    ``stub`` (without ``d``), by name: a twin leaves out what its dimension fixes. The overload
    is resolved while typing, so only the twin of the caller's dimension is compiled; a
    run-time ``d`` is made a literal first (see :func:`force_literal`). Returns ``stub``, whose
    Python body serves calls from Python.
    """
    names = inspect.getfullargspec(stub).args
    position = names.index("d")
    implementations = {}
    for dimension, twin in twins.items():
        twin_names = inspect.getfullargspec(twin.py_func).args
        if not set(twin_names) <= set(names) - {"d"}:
            raise ValueError(f"{twin_names} are not arguments of {stub.__name__}{tuple(names)}")
        forwarded = ", ".join(twin_names)
        # Named after the stub and the dimension, as profiles and numba's messages show it.
        name = f"{stub.__name__}_{dimension}d"
        namespace = {"twin": twin, "__name__": stub.__module__}
        source = f"def {name}({', '.join(names)}):\n    return twin({forwarded})\n"
        exec(source, namespace)  # noqa: S102 - a fixed template over the stub's own argument names
        implementations[dimension] = namespace[name]

    # numba reads the typing function's signature, which functools.wraps makes the stub's.
    @functools.wraps(stub)
    def typing(*argument_types):
        dimension = literal_id(argument_types[position])
        if dimension is None:
            return force_literal(stub, "d")
        return implementations[dimension]

    compiled_overload(stub, prefer_literal=True)(typing)
    return stub
