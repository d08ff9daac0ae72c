"""PETSc's options database as the solvers use it: options in for a solve, checked, and read.

:func:`options_in_database` puts a solver's options under its prefix for the duration of a
solve and takes them out again.

:func:`check_petsc_options` lets PETSc read the options in throwaway solvers on
``MPI.COMM_SELF`` under a private prefix, before anything is solved or written, and turns what
PETSc refuses (an unknown ``ksp_type``, ``ksp_rtol=abc``) into a :class:`ValueError` that names
the option. The options that PETSc reads only while a solver is set up (those of GAMG, of the
multigrid levels' smoothers, of MUMPS) are read in a throwaway of the kind that reads them.

:func:`unused_petsc_options` tells, after a run, which of the options no solver read. PETSc
marks every option in its database when something looks it up (``PetscOptionsUsed``, what
``-options_left`` prints at exit). The solvers' own options are in the database only around
each solve (:func:`options_in_database` removes them, and
their marks with them), so that context manager calls :func:`remember_read_options` before it
removes them, and the names PETSc marked are kept here for the rest of the process. petsc4py
3.18 has no getter for the marks: they are asked of the loaded PETSc library through
:mod:`ctypes`.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import re
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from petsc4py import PETSc

from dolfinx_invertible import _compat

__all__ = [
    "check_petsc_options",
    "forget_read_options",
    "options_in_database",
    "remember_read_options",
    "unused_petsc_options",
]

#: The prefix under which :func:`check_petsc_options` lets the throwaway solvers read options.
CHECK_PREFIX = "dolfinx_invertible_option_check_"

# Full names (prefix and name, lower case: PETSc's names are case-insensitive) of the options
# that PETSc marked read while options_in_database had them in the database.
_READ: set[str] = set()

# Options of solvers inside the solver (multigrid levels, their coarse solve, Chebyshev's
# eigenvalue estimate, block Jacobi's and ASM's blocks), read while the outer one is set up.
_INNER_SOLVER = re.compile(r"(mg_levels_(\d+_)?|mg_coarse_|esteig_|sub_|redundant_)")

# Words of the options that make PETSc open a viewer (a file for a value such as
# ascii:monitor.txt): the check leaves them to the solver rather than create the file.
_VIEWER_WORDS = ("monitor", "view", "converged_reason", "draw")

# Types whose options the check does not read in a throwaway: python imports the module the
# options name, shell has nothing to read.
_NOT_PROBED = {"python", "shell"}

# SNES types that need a DM with a decomposition, which this package's solvers do not have: the
# solve fails (PETSc 3.18: "DM has no default decomposition defined"), and a throwaway SNES
# without a function crashes in SNESSetFromOptions (a segmentation fault).
_NEED_A_DM = {"aspin"}


# -- PETSc's library, for what petsc4py 3.18 does not expose --------------------------------
@functools.cache
def _library() -> ctypes.CDLL | None:
    """Return PETSc's C library as loaded by petsc4py, or ``None`` where it cannot be reached."""
    try:
        # dlopen of petsc4py's extension (loaded already) finds the symbols of libpetsc, which
        # it links, whether petsc4py is Debian's, a wheel's or a source build.
        library = ctypes.CDLL(PETSc.__file__)
        used, message = library.PetscOptionsUsed, library.PetscErrorMessage
    except (OSError, AttributeError):
        return None
    used.argtypes = [ctypes.c_void_p, ctypes.c_char_p, ctypes.POINTER(ctypes.c_int)]
    used.restype = ctypes.c_int
    text = ctypes.POINTER(ctypes.c_char_p)
    message.argtypes = [ctypes.c_int, text, text]
    message.restype = ctypes.c_int
    return library


def _marked_read(full_name: str) -> bool | None:
    """Tell whether PETSc marked ``full_name`` (no dash) read.

    ``False`` if it is not in the database, ``None`` if the library cannot tell.
    """
    library = _library()
    if library is None:
        return None
    used = ctypes.c_int(0)
    # NULL is PETSc's global database, the one petsc4py's PETSc.Options() works on.
    if library.PetscOptionsUsed(None, full_name.encode(), ctypes.byref(used)) != 0:
        return None
    return bool(used.value)


def _what_petsc_said(error: PETSc.Error) -> str:
    """Return PETSc's own message of ``error`` (the one its traceback prints), short."""
    library = _library()
    if library is None:
        return f"PETSc error {error.ierr}"
    generic, specific = ctypes.c_char_p(), ctypes.c_char_p()
    library.PetscErrorMessage(int(error.ierr), ctypes.byref(generic), ctypes.byref(specific))
    kind = (generic.value or b"").decode(errors="replace").split(": http")[0].strip()
    detail = (specific.value or b"").decode(errors="replace").strip()
    if detail and kind:
        return f"PETSc: {detail} ({kind})"
    return f"PETSc: {detail or kind}" if detail or kind else f"PETSc error {error.ierr}"


# -- the check ------------------------------------------------------------------------------
def _typed(kind: type, name: str) -> str | None:
    """Return the type a ``ksp_<type>_...`` or ``pc_<type>_...`` option belongs to, if one."""
    word = name.split("_", 2)[1] if name.count("_") >= 2 else ""
    if word == "factor":  # lu, cholesky, ilu and icc read pc_factor_*
        return PETSc.PC.Type.LU
    types = {value for key, value in vars(kind.Type).items() if not key.startswith("_")}
    return word if word in types and word not in _NOT_PROBED else None


def _read_inner(prefix: str, name: str) -> None:
    """Let a throwaway of the kind that reads ``name`` read the options under ``prefix``."""
    match = _INNER_SOLVER.match(name)
    if match:
        _read_inner(prefix + match.group(0), name[match.end() :])
        return
    if name.startswith(("mat_mumps_icntl_", "mat_mumps_cntl_")):
        # MUMPS reads its controls when it factorises: parse them as it will.
        options = PETSc.Options(prefix)
        parse = options.getInt if "_icntl_" in name else options.getReal
        parse(name)
        return
    families = {
        kind: _typed(kind, name)
        for kind in (PETSc.KSP, PETSc.PC)
        if name.startswith(f"{kind.__name__.lower()}_")
    }
    if prefix == CHECK_PREFIX and not any(families.values()):
        return  # the SNES's KSP and PC have read it
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    try:
        ksp.setOptionsPrefix(prefix)
        for kind, target in ((PETSc.KSP, ksp), (PETSc.PC, ksp.getPC())):
            if families.get(kind) is not None:
                try:
                    target.setType(families[kind])
                except PETSc.Error:  # a type this PETSc was built without
                    return
        ksp.setFromOptions()
    finally:
        ksp.destroy()


def _refused(options: Mapping[str, str | None]) -> str | None:
    """Return what PETSc says when throwaway solvers read ``options`` (``None``: nothing)."""
    # options.py imports this module (options_in_database calls remember_read_options).

    snes_type = options.get("snes_type")
    if snes_type is not None and snes_type.lower() in _NEED_A_DM:
        return f"SNES type {snes_type} needs a DM with a decomposition, which the solvers lack"
    with options_in_database(CHECK_PREFIX, options), _compat.petsc_errors_untold():
        try:
            snes = PETSc.SNES().create(PETSc.COMM_SELF)
            try:
                snes.setOptionsPrefix(CHECK_PREFIX)
                snes.setFromOptions()  # the SNES, its line search, KSP and PC
            finally:
                snes.destroy()
            for name in options:
                _read_inner(CHECK_PREFIX, name.lower())
        except PETSc.Error as error:
            return _what_petsc_said(error)
    return None


def _shown(name: str, value: str | None) -> str:
    return f"--petsc-option {name}" if value in (None, "") else f"--petsc-option {name}={value}"


def check_petsc_options(
    options: dict[str, str | None], *, prefix: str = "dolfinx_invertible_"
) -> None:
    """Refuse solver options that PETSc would refuse, naming the option.

    PETSc reads the options in throwaway solvers on ``MPI.COMM_SELF`` under a private prefix
    (:data:`CHECK_PREFIX`): a SNES with its line search, KSP and PC, then, for the options that
    PETSc reads only while a solver is set up, a KSP of the kind that reads them (a
    ``pc_gamg_*`` option in a GAMG preconditioner, ``mg_levels_ksp_*`` in a level's smoother,
    ``mat_mumps_icntl_*`` parsed as MUMPS does). Unknown types (``ksp_type``, ``pc_type``,
    ``snes_type``, ``snes_linesearch_type``, ...) and values that are not numbers or booleans
    where PETSc wants one are refused. Options that make PETSc open a viewer (``*monitor*``,
    ``*view*``, ``*converged_reason``) are left to the solver when they have a value, which
    may name a file; options that no solver reads are not refused
    (:func:`unused_petsc_options`).

    Every rank checks on its own (no collective call): called with the same options on every
    rank, it raises on every rank. PETSc's database is left as it was found, and PETSc prints
    nothing.

    Parameters
    ----------
    options
        The solver's options as the command line hands them to the solver: without the
        solver's prefix, e.g. ``{"ksp_type": "cg", "ksp_rtol": "1e-8"}``; ``None`` or ``""`` as
        a value is a flag.
    prefix
        The solver's prefix; names that begin with it, or with dashes, are read without them.

    Raises
    ------
    ValueError
        For the first option PETSc refuses, e.g. ``--petsc-option ksp_type=notakrylov: PETSc:
        Unable to find requested KSP type notakrylov (Unknown type. ...)``.
    """
    readable: dict[str, tuple[str, str | None]] = {}
    for given, value in options.items():
        name = given.lstrip("-")
        if prefix and name.startswith(prefix):
            name = name[len(prefix) :]
        opens_a_viewer = any(word in name.lower() for word in _VIEWER_WORDS)
        if not (opens_a_viewer and value not in (None, "")):
            readable[name] = (given, value)
    values = {name: value for name, (_, value) in readable.items()}
    if not values or _refused(values) is None:
        return
    # Which one: each alone, then (an option refused only beside others) all of them.
    for name, (given, value) in readable.items():
        said = _refused({name: value})
        if said is not None:
            raise ValueError(f"{_shown(given, value)}: {said}")
    shown = ", ".join(_shown(given, value) for given, value in readable.values())
    raise ValueError(f"{shown}: {_refused(values)}")


# -- options no solver read -----------------------------------------------------------------
def remember_read_options(prefix: str, names: Iterable[str]) -> None:
    """Keep which of ``names`` under ``prefix`` PETSc marked read, before they are removed.

    Called by :func:`options_in_database` as it takes its
    options out of the database (PETSc forgets an option's mark with the option). Never raises.
    """
    if prefix == CHECK_PREFIX:  # the check's throwaway solvers read everything they are given
        return
    for name in names:
        full = f"{prefix}{name}".lstrip("-").lower()
        if full not in _READ and _marked_read(full):
            _READ.add(full)


def forget_read_options() -> None:
    """Forget the options remembered as read, e.g. before a second run in the same process."""
    _READ.clear()


def unused_petsc_options(
    given: Iterable[str], *, prefix: str = "dolfinx_invertible_", comm=None
) -> list[str]:
    """Return the names of ``given`` that no solver has read, in their order.

    An option counts as read if PETSc marked it read while it was in the database: for the
    solvers' options, at any solve so far in the process (or since :func:`forget_read_options`);
    for options the database still holds (e.g. ones without the solver's prefix), now. Where
    the PETSc library cannot be asked (:mod:`ctypes`), every option counts as read.

    Parameters
    ----------
    given
        Option names as the user gave them (a dict's keys will do), relative to ``prefix``:
        for the solver's options (``prefix`` the solver's), e.g. ``["ksp_rtol",
        "ksp_rtoll"]``; for options given to PETSc's database without a prefix, pass
        ``prefix=""``. Leading dashes are ignored.
    prefix
        The prefix the solvers read the options under.
    comm
        An MPI communicator: an option counts as read if a solver read it on any of its ranks,
        and every rank returns the same list. Collective over ``comm``; ``None`` asks this rank
        only.

    Returns
    -------
    list[str]
        The names of ``given``, unchanged, that were not read.
    """
    names = list(dict.fromkeys(given))
    read = []
    for name in names:
        full = f"{prefix}{name.lstrip('-')}".lower()
        marked = full in _READ or _marked_read(full)
        if marked is None or marked:
            read.append(name)
    if comm is not None and comm.size > 1:
        read = [name for part in comm.allgather(read) for name in part]
    read_anywhere = set(read)
    return [name for name in names if name not in read_anywhere]


@contextlib.contextmanager
def options_in_database(prefix: str, options: dict[str, Any]) -> Iterator[None]:
    """Put ``options`` under ``prefix`` in PETSc's global database for the duration.

    Names already present (from the command line or the caller's own ``PETSc.Options``) are left
    alone, so they take precedence. Ours are removed afterwards so they cannot leak into another
    solver that shares the prefix; they are pushed again around every solve because PETSc reads
    some options lazily, e.g. those of multigrid levels, which GAMG creates during setup.
    """
    database = PETSc.Options(prefix)
    # The names present, read without marking them read as hasName would: which options a
    # solver read is told by PETSc's marks (petsc_options.unused_petsc_options), and a nested
    # call would otherwise mark every option of the outer one.
    present = {name.lower() for name in PETSc.Options().getAll()}
    added = []
    for name, value in options.items():
        if f"{prefix}{name}".lower() in present:
            continue
        database.setValue(name, value)
        present.add(f"{prefix}{name}".lower())
        added.append(name)
    try:
        yield
    finally:
        # PETSc forgets an option's read mark with the option: keep the marks first.
        remember_read_options(prefix, added)
        for name in added:
            database.delValue(name)
