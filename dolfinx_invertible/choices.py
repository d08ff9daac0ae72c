"""Every option's choices, defined once: the registry the solvers, the scenes and the CLI read.

Each :class:`Choices` maps a choice's name (as the command line and the keyword arguments spell
it) to one line saying what it does; some also name what implements it, as ``"module:name"``,
resolved by the owner on first use. The owners validate against these registries
(:class:`~dolfinx_invertible.HyperelasticProblem`, the minimiser,
:class:`~dolfinx_invertible.ImplicitDynamics`, :class:`~dolfinx_invertible.scenes.Parameters`),
the command line builds its options from them, and the option tables of docs/guide.md are
generated from them (``python -m dolfinx_invertible.scenes.parameters --markdown``). Adding a
choice is one entry here and its implementation where the entry points.

This module imports nothing, so that the command line's parser loads neither PETSc nor DOLFINx.
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from typing import Any

__all__ = [
    "ELASTIC_ROUTES",
    "EXTENSIONS",
    "GLOBALIZATIONS",
    "LINEAR_SOLVERS",
    "MODELS",
    "OUTPUT_FORMATS",
    "PRECONDITIONERS",
    "SCHEMES",
    "TANGENTS",
    "Choice",
    "Choices",
]


class Choice:
    """One choice of an option: its description and, where it has one, what implements it."""

    def __init__(self, description: str, target: str | None = None, value: Any = None) -> None:
        self.description = description
        self.target = target
        self.value = value

    def resolve(self) -> Any:
        """Import and return the implementation ``"module:name"`` (``None`` if it has none)."""
        if self.target is None:
            return None
        module, _, name = self.target.partition(":")
        return getattr(importlib.import_module(module), name)


class Choices(Mapping[str, Choice]):
    """The choices of one option, in the order they are listed.

    Parameters
    ----------
    option
        The option as the command line spells it, e.g. ``"--linear-solver"`` (for messages).
    keyword
        The keyword argument of the API that takes it, e.g. ``"linear_solver"``.
    entries
        Name → :class:`Choice`.
    """

    def __init__(self, option: str, keyword: str, entries: dict[str, Choice]) -> None:
        self.option = option
        self.keyword = keyword
        self._entries = dict(entries)

    def __getitem__(self, name: str) -> Choice:
        return self._entries[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def names(self) -> tuple[str, ...]:
        """The names, in order."""
        return tuple(self._entries)

    def check(self, value: Any, *, command_line: bool = False) -> None:
        """Raise ``ValueError`` naming the option and the choices if ``value`` is not one."""
        if value not in self._entries:
            name = self.option if command_line else self.keyword
            raise ValueError(f"{name} must be one of {', '.join(self.names)}, got {value!r}")

    def resolve(self, name: str) -> Any:
        """Return the implementation of the choice ``name`` (checked)."""
        self.check(name)
        return self._entries[name].resolve()

    def value(self, name: str) -> Any:
        """Return the API value the command-line name ``name`` stands for (checked)."""
        self.check(name)
        return self._entries[name].value


_CONSTITUTIVE = "dolfinx_invertible.constitutive"
_INTEGRATORS = "dolfinx_invertible.solvers.integrators"

#: ``--model``: the isotropic energies (:mod:`dolfinx_invertible.constitutive.models`).
MODELS = Choices(
    "--model",
    "model",
    {
        "neo-hookean": Choice("μ/2 (I₁ − d) − μ ln J + λ/2 (ln J)²", f"{_CONSTITUTIVE}:NeoHookean"),
        "corotated": Choice("μ Σ(σᵢ − 1)² + λ/2 (Σ(σᵢ − 1))²", f"{_CONSTITUTIVE}:Corotated"),
        "fixed-corotated": Choice(
            "μ Σ(σᵢ − 1)² + λ/2 (J − 1)² (paper §3.4)", f"{_CONSTITUTIVE}:FixedCorotated"
        ),
        "stable-neo-hookean": Choice(
            "Smith et al. 2018, defined through inversion", f"{_CONSTITUTIVE}:StableNeoHookean"
        ),
        "arap": Choice("as rigid as possible, μ Σ(σᵢ − 1)²", f"{_CONSTITUTIVE}:ARAP"),
        "stvk": Choice("St. Venant–Kirchhoff", f"{_CONSTITUTIVE}:StVK"),
    },
)

#: ``--extension``: the invertible extensions (:mod:`dolfinx_invertible.constitutive.extensions`).
EXTENSIONS = Choices(
    "--extension",
    "extension",
    {
        "none": Choice("the model's own energy everywhere"),
        "c1": Choice(
            "C1 extension below ε on each singular value (paper §4.1)", f"{_CONSTITUTIVE}:C1"
        ),
        "c2": Choice("C2 extension below ε on J (paper §4.2)", f"{_CONSTITUTIVE}:C2"),
        "ife": Choice("invertible finite elements: a stress, no energy", f"{_CONSTITUTIVE}:IFE"),
    },
)

#: ``--project`` / ``project=``: which tangent Newton uses.
TANGENTS = Choices(
    "--project",
    "project",
    {
        "auto": Choice("exact, projected where the exact one gives no descent", value="auto"),
        "yes": Choice("SPD-projected", value=True),
        "no": Choice("exact", value=False),
    },
)

#: ``--elastic`` / ``elastic=``: how the elastic energy is assembled.
ELASTIC_ROUTES = Choices(
    "--elastic",
    "elastic",
    {
        "kernels": Choice("this package's numba cell kernels"),
        "ufl": Choice("DOLFINx's own route: plain Neo-Hookean in UFL, compiled by FFCx"),
    },
)

#: ``--linear-solver`` / ``linear_solver=``: Newton's linear solves
#: (:func:`~dolfinx_invertible.solvers.options.linear_solver_options`).
LINEAR_SOLVERS = Choices(
    "--linear-solver",
    "linear_solver",
    {
        "auto": Choice("direct up to DIRECT_SOLVE_LIMIT unknowns (4× in 2D), iterative above"),
        "direct": Choice("a sparse factorisation (MUMPS, SuperLU_dist)"),
        "iterative": Choice(
            "conjugate gradients on the exact tangent, AMG on the projected one, stopped at "
            "negative curvature"
        ),
    },
)

#: ``--pc`` / ``pc=``: the algebraic multigrid of the iterative path.
PRECONDITIONERS = Choices(
    "--pc",
    "pc",
    {
        "gamg": Choice("PETSc's GAMG with the rigid-body near-nullspace"),
        "hypre": Choice("hypre's BoomerAMG"),
    },
)

#: ``--globalization`` / ``globalization=``: how Newton's steps are kept safe
#: (:mod:`~dolfinx_invertible.solvers.trust_region`).
GLOBALIZATIONS = Choices(
    "--globalization",
    "globalization",
    {
        "auto": Choice("the trust region on the iterative path, the line search on the direct one"),
        "line-search": Choice("energy backtracking along the Newton direction"),
        "trust-region": Choice(
            "a trust region around CG on the exact tangent, following negative curvature "
            "(iterative path only)"
        ),
    },
)

#: ``--scheme`` / ``scheme=``: the time integrators of
#: :class:`~dolfinx_invertible.ImplicitDynamics` (:mod:`dolfinx_invertible.solvers.integrators`).
SCHEMES = Choices(
    "--scheme",
    "scheme",
    {
        "backward-euler": Choice(
            "first order, L-stable, damps strongly", f"{_INTEGRATORS}.backward_euler:BackwardEuler"
        ),
        "bdf2": Choice("second order, A-stable, variable step", f"{_INTEGRATORS}.bdf2:BDF2"),
        "newmark": Choice(
            "average acceleration (γ = 1/2, β = 1/4): second order, no numerical damping",
            f"{_INTEGRATORS}.newmark:Newmark",
        ),
    },
)

#: ``--format``: what a scene run writes (:mod:`dolfinx_invertible.scenes.outputs`).
OUTPUT_FORMATS = Choices(
    "--format",
    "output_format",
    {
        "xdmf": Choice("XDMF3 + HDF5, one file per step (ParaView's XDMF3 reader, every DOLFINx)"),
        "vtx": Choice("ADIOS2 VTX, the displacement at full order (DOLFINx with ADIOS2)"),
        "both": Choice("XDMF and VTX"),
    },
)
