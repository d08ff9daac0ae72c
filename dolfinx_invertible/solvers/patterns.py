"""Copies and sums of the solver's matrices when energy terms grow their sparsity pattern.

The forms fix a pattern; an energy term may add couplings outside it (contact between two
surface vertices that come close), and the matrices it is assembled into then grow. Such a term
inserts, at every assembly, every coupling it ever inserted (zeros where they do not act now):
the pattern of any matrix is then the forms' plus the term's couplings up to its last assembly,
so the patterns of two matrices are nested, and equal exactly when their numbers of nonzeros
are. :func:`structure` turns that into the PETSc structure flag of a copy or a sum.
"""

from __future__ import annotations

from petsc4py import PETSc

__all__ = ["copy_into", "structure"]

SAME = PETSc.Mat.Structure.SAME_NONZERO_PATTERN
SUBSET = PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN
DIFFERENT = PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN


def structure(source: PETSc.Mat, target: PETSc.Mat) -> PETSc.Mat.Structure:
    """Return how ``source``'s pattern relates to ``target``'s: same, subset or different.

    Assumes nested patterns (see the module description). Collective.
    """
    total = PETSc.Mat.InfoType.GLOBAL_SUM
    source_count = source.getInfo(total)["nz_used"]
    target_count = target.getInfo(total)["nz_used"]
    if source_count == target_count:
        return SAME
    return SUBSET if source_count < target_count else DIFFERENT


def copy_into(source: PETSc.Mat, target: PETSc.Mat | None) -> PETSc.Mat:
    """Copy ``source`` into ``target`` and return it; a new matrix if ``target`` is None.

    A target of another pattern is copied into value by value (PETSc's general copy), after
    allowing it to grow.
    """
    if target is None:
        return source.copy()
    relation = structure(source, target)
    if relation != SAME:
        target.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
        relation = DIFFERENT
    source.copy(target, structure=relation)
    return target
