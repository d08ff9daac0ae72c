"""The ids of registered classes: each class declares its own, the registry checks them.

The compiled kernels branch on a model's ``model_id`` and an extension's ``extension_id`` as
compile-time literals, and numba's disk cache keys the compiled chains on them, so an id is part
of the class's contract: written on the class, never derived from where a registry lists it.
"""

from __future__ import annotations

__all__ = ["ordered_by_id"]


def ordered_by_id(classes: tuple[type, ...], attribute: str, *, first: int) -> tuple[type, ...]:
    """Return ``classes`` sorted by their ids, once the ids are checked.

    Each class must declare ``attribute`` itself (not inherit it) as an ``int``, no two classes
    may share an id, and the ids must run ``first, first + 1, ...`` without a gap, so that a
    registry can index its classes by id.

    Parameters
    ----------
    classes
        The registered classes, in any order.
    attribute
        The name of the id attribute (``"model_id"``, ``"extension_id"``).
    first
        The id the lowest class must have.

    Raises
    ------
    ValueError
        Naming the classes whose ids are missing, repeated or leave a gap.
    """
    undeclared = [
        cls.__name__
        for cls in classes
        if type(vars(cls).get(attribute)) is not int  # noqa: E721 - bool is no id
    ]
    if undeclared:
        raise ValueError(
            f"{', '.join(undeclared)} must declare an integer {attribute} as a class attribute"
        )
    by_id: dict[int, type] = {}
    for cls in classes:
        identifier = vars(cls)[attribute]
        if identifier in by_id:
            raise ValueError(
                f"{by_id[identifier].__name__} and {cls.__name__} both declare "
                f"{attribute} = {identifier}"
            )
        by_id[identifier] = cls
    expected = list(range(first, first + len(classes)))
    if sorted(by_id) != expected:
        declared = ", ".join(f"{cls.__name__} = {identifier}" for identifier, cls in by_id.items())
        raise ValueError(
            f"the {attribute}s must be {expected[0]}..{expected[-1]} without a gap; "
            f"declared: {declared}"
        )
    return tuple(by_id[identifier] for identifier in expected)
