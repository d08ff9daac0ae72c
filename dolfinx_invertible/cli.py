"""The command line: ``python -m dolfinx_invertible`` or ``dolfinx-invertible`` (also under MPI).

Subcommands:

- ``list``: every scene with a one-line description and its paper figure;
- ``run SCENE [options] [PETSc options]``: run a scene (``run SCENE --help`` lists its options
  with their units and this scene's defaults); writes ``results/SCENE/`` (see
  :mod:`dolfinx_invertible.scenes.runner`);
- ``report NAME``: a report (``report --help`` lists them);
- ``compile``: compile the DOLFINx cell kernels of the default materials
  (:data:`~dolfinx_invertible.fem.kernels.DEFAULT_MATERIALS`, 2D and 3D) into numba's disk
  cache, so that the first assembly of a script does not pay for it (``make setup`` runs it);
- ``bench NAME``: a benchmark (``bench --help`` lists them), from a source checkout: the
  benchmarks are the repository's ``benchmarks/`` folder beside the package, not installed.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import logging
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

__all__ = ["main", "parser"]

# Generic scene options: (name, attribute, type, metavar, help with {default}). Options that
# apply only to dynamic or only to quasi-static scenes are marked.
_DYNAMIC_ONLY = {"density", "dt", "t_end", "scheme", "damping"}


def _compile(arguments: argparse.Namespace) -> int:
    from dolfinx_invertible.fem import kernels

    start = time.perf_counter()
    seconds = kernels.precompile()
    per_material: dict[str, float] = {}
    for (_, dimension, material), value in seconds.items():
        key = f"{material} {dimension}D"
        per_material[key] = per_material.get(key, 0.0) + value
    details = "\n".join(f"  {key}: {value:.1f} s" for key, value in per_material.items())
    paths = sum(1 for kind, _, _ in seconds if kind == "svd path")
    print(
        f"{len(seconds) - paths} kernels and {paths} SVD paths compiled or loaded from the cache "
        f"in {time.perf_counter() - start:.1f} s:\n{details}"
    )
    return 0


def _benchmarks():
    """Return the ``benchmarks`` package of the source checkout of this package, or None.

    The benchmarks are not installed: in a checkout they sit beside the package directory, at
    the repository root (with ``pyproject.toml``), and are loaded from there by path, so that
    no other ``benchmarks`` on ``sys.path`` stands in for them. One already loaded (``python
    -m benchmarks``, the tests) is taken as it is.
    """
    loaded = sys.modules.get("benchmarks")
    if loaded is not None:
        return loaded
    root = Path(__file__).resolve().parent.parent
    folder = root / "benchmarks"
    if not ((folder / "__init__.py").is_file() and (root / "pyproject.toml").is_file()):
        return None
    specification = importlib.util.spec_from_file_location(
        "benchmarks", folder / "__init__.py", submodule_search_locations=[str(folder)]
    )
    package = importlib.util.module_from_spec(specification)
    sys.modules["benchmarks"] = package
    specification.loader.exec_module(package)
    return package


def _no_benchmarks(arguments: argparse.Namespace) -> int:
    print(
        "error: the benchmarks run from a source checkout of dolfinx_invertible (its "
        "benchmarks/ folder); this installed package has none",
        file=sys.stderr,
    )
    return 2


def _list(arguments: argparse.Namespace) -> int:
    from dolfinx_invertible.scenes import SCENES, get_scene

    scenes = [get_scene(name) for name in SCENES]
    width = max(len(scene.name) for scene in scenes)
    for scene in scenes:
        kind = "dynamic" if scene.dynamic else "quasi-static"
        print(f"{scene.name:<{width}}  {scene.description} [{scene.figure}; {kind}]")
    return 0


def _scene_options(subparser: argparse.ArgumentParser, scene) -> None:
    """Add the generic options to a scene's parser, with that scene's defaults in the help."""
    from dolfinx_invertible.scenes.parameters import (
        EXTENSION_NAMES,
        GLOBALIZATIONS,
        LINEAR_SOLVERS,
        MODEL_NAMES,
        OUTPUT_FORMATS,
        PRECONDITIONERS,
        PROJECT_CHOICES,
        Parameters,
    )

    defaults = Parameters(**scene.defaults)

    def default(name):
        return getattr(defaults, name)

    group = subparser.add_argument_group("material")
    group.add_argument(
        "--model", choices=list(MODEL_NAMES), help=f"energy model (default: {default('model')})"
    )
    group.add_argument(
        "--extension",
        choices=list(EXTENSION_NAMES),
        help="invertible extension (default: c2 for neo-hookean, which is undefined at J <= 0; "
        "none for the other models, which are defined through inversion)",
    )
    group.add_argument("--E", type=float, metavar="PA", help=f"Young's modulus [Pa] "
                       f"(default: {default('E'):g})")  # fmt: skip
    group.add_argument("--nu", type=float, metavar="NU", help=f"Poisson ratio, in (-1, 0.5) "
                       f"(default: {default('nu'):g})")  # fmt: skip
    group.add_argument("--eps", type=float, metavar="EPS", help="extension threshold, in (0, 1): "
                       "on J for c2 and ife (default 0.9), on each singular value for c1 "
                       "(default 0.4)")  # fmt: skip
    group.add_argument("--k", type=float, metavar="K", help="c1 penalty stiffness [Pa] "
                       "(default: 20 E)")  # fmt: skip
    if scene.dynamic:
        group.add_argument("--density", type=float, metavar="RHO", help=f"mass density "
                           f"[kg/m^3] (default: {default('density'):g})")  # fmt: skip
        time_group = subparser.add_argument_group("time stepping")
        time_group.add_argument("--dt", type=float, metavar="DT", help=f"largest time step [s] "
                                f"(default: {default('dt'):g})")  # fmt: skip
        time_group.add_argument("--steps", type=int, metavar="N", help="stop after N steps of "
                                "dt (at t = N dt, at most --t-end); the scene's loading keeps "
                                "its schedule over --t-end")  # fmt: skip
        time_group.add_argument("--t-end", type=float, metavar="T", dest="t_end", help=f"end "
                                f"time [s] (default: {default('t_end'):g})")  # fmt: skip
        time_group.add_argument("--scheme", choices=["backward-euler", "bdf2"],
                                help=f"time integrator (default: {default('scheme')})")  # fmt: skip
        time_group.add_argument("--damping", type=float, metavar="ZETA", help="mass-proportional "
                                "damping as a fraction of critical damping of the lowest mode "
                                f"(default: {default('damping'):g})")  # fmt: skip
    else:
        group = subparser.add_argument_group("load stepping")
        group.add_argument("--steps", type=int, metavar="N", help=f"load steps (default: "
                           f"{default('steps')})")  # fmt: skip
    discretisation = subparser.add_argument_group("discretisation and solver")
    discretisation.add_argument("--resolution", type=int, metavar="N", help=f"mesh resolution, "
                                f"cells along the shortest edge (default: "
                                f"{default('resolution')})")  # fmt: skip
    discretisation.add_argument("--degree", type=int, choices=[1, 2], help=f"Lagrange degree "
                                f"(default: {default('degree')})")  # fmt: skip
    discretisation.add_argument("--size", type=float, metavar="L", help=f"size of the body [m] "
                                f"(default: {default('size'):g})")  # fmt: skip
    for name, values in scene.choices.items():
        if name == "mesh" and scene.takes_mesh_file:
            continue
        discretisation.add_argument(f"--{name}", choices=list(values),
                                    type=type(values[0]), help=f"{name} (default: "
                                    f"{default(name)})")  # fmt: skip
    if scene.takes_mesh_file:
        names = " | ".join(scene.choices.get("mesh", ()))
        discretisation.add_argument("--mesh", metavar="PATH" if not names else f"{{{names}}}|PATH",
                                    help="the body: a gmsh .msh or XDMF mesh file of "
                                    "straight tetrahedra, fitted into the box the scene's "
                                    "own body fills (--resolution does not apply)"
                                    + (f", or one of {names} (default: {default('mesh')})"
                                       if names else ""))  # fmt: skip
    discretisation.add_argument("--project", choices=list(PROJECT_CHOICES), help="tangent: auto "
                                "(exact, projected where the exact one gives no descent), yes "
                                "(SPD-projected), no (exact) (default: "
                                f"{default('project')})")  # fmt: skip
    discretisation.add_argument("--elastic", choices=["kernels", "ufl"], help="how the elastic "
                                "energy is assembled: this package's kernels, or DOLFINx's own "
                                "route (plain Neo-Hookean in UFL, compiled by FFCx) (default: "
                                f"{default('elastic')})")  # fmt: skip
    discretisation.add_argument("--inversion-free", type=float, metavar="FRACTION",
                                dest="inversion_free", help="cap Newton steps so that no point's "
                                "volume falls below FRACTION of its current value (default: "
                                f"{default('inversion_free')})")  # fmt: skip
    discretisation.add_argument("--linear-solver", choices=list(LINEAR_SOLVERS),
                                dest="linear_solver", help="Newton's linear solves: a sparse "
                                "factorisation (direct), conjugate gradients on the exact tangent "
                                "preconditioned by AMG on the projected one, stopped at negative "
                                "curvature (iterative), or auto: direct up to "
                                "DIRECT_SOLVE_LIMIT unknowns (docs/guide.md) (default: "
                                f"{default('linear_solver')})")  # fmt: skip
    discretisation.add_argument("--pc", choices=list(PRECONDITIONERS), help="AMG of the "
                                "iterative path: PETSc's GAMG or hypre's BoomerAMG (default: "
                                f"{default('pc')})")  # fmt: skip
    discretisation.add_argument("--globalization", choices=list(GLOBALIZATIONS), help="how "
                                "Newton's steps are kept safe: the energy line search, or a "
                                "trust region around conjugate gradients on the exact tangent "
                                "that follows negative curvature (the iterative path only); "
                                "auto: the trust region on the iterative path, the line "
                                "search on the direct one (default: "
                                f"{default('globalization')})")  # fmt: skip
    resumable = "; a run stopped so goes on with --resume DIR --max-cuts M" if scene.dynamic else ""
    discretisation.add_argument("--max-cuts", type=int, metavar="N", dest="max_cuts",
                                help="consecutive halvings of a failing step before the run "
                                f"stops{resumable} (default: {default('max_cuts')})")  # fmt: skip
    if scene.takes_friction or scene.several_bodies or scene.takes_self_contact:
        discretisation.add_argument("--friction", type=float, metavar="MU", help="Coulomb's "
                                    "friction coefficient of the contacts, lagged per time step "
                                    f"(default: {default('friction'):g})")  # fmt: skip
        discretisation.add_argument("--friction-velocity", type=float, metavar="EPS_V",
                                    dest="friction_velocity", help="slip speed [m/s] below "
                                    "which friction sticks (elastically) (default: "
                                    f"{default('friction_velocity'):g})")  # fmt: skip
    if scene.several_bodies:
        discretisation.add_argument("--count", type=int, metavar="N", help="number of bodies "
                                    f"(default: {default('count')})")  # fmt: skip
    if scene.takes_self_contact or scene.self_contact_refusal:
        discretisation.add_argument("--self-contact", action="store_const", const=True,
                                    dest="self_contact", help="keep the body's surface from "
                                    "passing through itself: IPC Toolkit's barrier between "
                                    "surface primitives closer than d̂ and continuous collision "
                                    "detection on every Newton step (docs/contact.md)")  # fmt: skip
    discretisation.add_argument("--petsc-option", action="append", default=[],
                                metavar="NAME=VALUE", dest="petsc_option", help="a PETSc "
                                "option of the solver, without prefix or dash, e.g. "
                                "ksp_rtol=1e-8 or snes_monitor= (repeatable; -NAME VALUE with the "
                                "dolfinx_invertible_ prefix works too)")  # fmt: skip
    output = subparser.add_argument_group("output")
    output.add_argument("--out", type=Path, metavar="DIR", help=f"output directory (default: "
                        f"results/{scene.name})")  # fmt: skip
    output.add_argument("--quiet", action="store_true", help="no progress bar")
    output.add_argument("--verbose", action="store_true", help="show compiler and solver "
                        "chatter (FFCx, cffi, numba warnings)")  # fmt: skip
    output.add_argument("--format", choices=list(OUTPUT_FORMATS), default="xdmf",
                        dest="output_format", help="xdmf (ParaView's XDMF3 reader, every "
                        "DOLFINx), vtx (ADIOS2 VTX: the displacement at full order; needs "
                        "DOLFINx with ADIOS2, not bookworm's 0.5.2) or both "
                        "(default: xdmf)")  # fmt: skip
    if scene.dynamic:
        output.add_argument("--checkpoint-every", type=int, metavar="N", default=10,
                            dest="checkpoint_every", help="write DIR/checkpoint.npz every N "
                            "steps and after the last one, to --resume from (0: never; "
                            "default: 10)")  # fmt: skip
        output.add_argument("--resume", type=Path, metavar="DIR", help="continue the stopped "
                            "run in DIR from its checkpoint, with its own parameters (--t-end "
                            "may be later), appending to its output")  # fmt: skip


def _parameters(scene, arguments: argparse.Namespace):
    from dolfinx_invertible.scenes.parameters import Parameters

    values = dict(scene.defaults)
    for name in Parameters.__dataclass_fields__:
        given = getattr(arguments, name, None)
        if given is not None:
            values[name] = given
    if scene.dynamic and getattr(arguments, "steps", None) is not None:
        if arguments.steps < 1:
            raise ValueError(f"--steps must be an integer >= 1, got {arguments.steps!r}")
        values["t_stop"] = values.pop("steps") * values.get("dt", Parameters.dt)
    if getattr(arguments, "extension", None) is None:
        values.setdefault(
            "extension", "c2" if values.get("model", Parameters.model) == "neo-hookean" else "none"
        )
    return Parameters(**values)


def _resumed_parameters(scene, arguments: argparse.Namespace):
    """Return the parameters of the run in ``--resume DIR``, with a later ``--t-end`` if given.

    The resumed run goes on to its end: where the first one stopped early (``--steps``) does
    not carry over. ``--max-cuts`` may change: a run whose cuts ran out continues with more.
    """
    from dolfinx_invertible.scenes.checkpoints import MAY_CHANGE_ON_RESUME, latest_checkpoint
    from dolfinx_invertible.scenes.parameters import Parameters

    # Where the first run stopped early (t_stop, from --steps) is not an option of the second.
    resumed = [name for name in MAY_CHANGE_ON_RESUME if name != "t_stop"]
    given = [
        name
        for name in Parameters.__dataclass_fields__
        if name not in resumed and getattr(arguments, name, None) is not None
    ]
    if given or arguments.out is not None:
        options = [f"--{name.replace('_', '-')}" for name in given]
        options += ["--out"] if arguments.out is not None else []
        raise ValueError(
            f"--resume continues the run with its own parameters and output: drop "
            f"{', '.join(options)}"
        )
    # The newest checkpoint, whole or in the ranks' parts (a run killed before its first
    # whole checkpoint has only these).
    values = latest_checkpoint(arguments.resume)[1]["parameters"]
    values["t_stop"] = None
    for name in resumed:
        if getattr(arguments, name, None) is not None:
            values[name] = getattr(arguments, name)
    return Parameters(**values)


def _petsc_options(extra: Sequence[str]) -> dict[str, str | None]:
    """Parse ``-name [value]`` pairs left over by argparse into PETSc options."""
    options: dict[str, str | None] = {}
    index = 0
    while index < len(extra):
        token = extra[index]
        if not token.startswith("-") or token.startswith("--") or len(token) < 2:
            raise ValueError(f"unrecognised argument {token!r} (PETSc options start with one '-')")
        value = None
        if index + 1 < len(extra) and not extra[index + 1].startswith("-"):
            value = extra[index + 1]
            index += 1
        options[token[1:]] = value
        index += 1
    return options


def _named_options(given: Sequence[str]) -> dict[str, str | None]:
    """Parse ``NAME=VALUE`` (``NAME=`` or ``NAME`` for a flag) into prefixed solver options."""
    options: dict[str, str | None] = {}
    for item in given:
        name, _, value = item.partition("=")
        name = name.strip().lstrip("-")
        if not name:
            raise ValueError(f"--petsc-option needs NAME=VALUE, got {item!r}")
        if not name.startswith(_PREFIX):
            name = _PREFIX + name
        options[name] = value or None
    return options


def _quiet_libraries(verbose: bool) -> None:
    """Silence FFCx/cffi build logs and numba warnings unless asked for."""
    if verbose:
        return
    # FFCx installs a root handler (logging.basicConfig) and cffi lowers the root logger's level
    # while it compiles, which prints every compiler command: filter at the handlers instead.
    import ffcx  # noqa: F401

    for handler in logging.getLogger().handlers:
        handler.setLevel(logging.WARNING)
    for name in ("ffcx", "UFL", "dolfinx", "numba"):
        logging.getLogger(name).setLevel(logging.WARNING)
    try:
        from numba.core.errors import NumbaWarning

        warnings.simplefilter("ignore", NumbaWarning)
    except ImportError:
        pass
    warnings.simplefilter("ignore", DeprecationWarning)


def _run(arguments: argparse.Namespace) -> int:
    from mpi4py import MPI

    from dolfinx_invertible.scenes import get_scene
    from dolfinx_invertible.scenes.runner import RunInterrupted

    comm = MPI.COMM_WORLD
    _quiet_libraries(arguments.verbose)
    scene = get_scene(arguments.scene)
    resume = getattr(arguments, "resume", None)
    try:
        if resume is not None:
            parameters, output = _resumed_parameters(scene, arguments), resume
        else:
            parameters = _parameters(scene, arguments)
            output = arguments.out or Path("results") / scene.name
        petsc = _petsc_options(arguments.petsc)
        petsc.update(_named_options(arguments.petsc_option))
        _check_combination(parameters, petsc, comm)
        from dolfinx_invertible.scenes.runner import run_scene

        summary = run_scene(
            scene,
            parameters,
            output=output,
            quiet=arguments.quiet or comm.rank != 0,
            petsc_options=_solver_options(petsc),
            comm=comm,
            checkpoint_every=getattr(arguments, "checkpoint_every", 0) or None,
            resume=resume is not None,
            output_format=arguments.output_format,
        )
    except ValueError as error:
        if arguments.verbose:
            raise
        if comm.rank == 0:
            print(f"error: {error}", file=sys.stderr)
        return 2
    except RunInterrupted as interrupt:
        if comm.rank == 0:
            print(f"{scene.name}: {interrupt}; summary written to {output / 'summary.json'}",
                  file=sys.stderr)  # fmt: skip
        return 130
    if comm.rank == 0:
        _print_summary(summary, output)
    return 0 if summary["completed"] else 1


_PREFIX = "dolfinx_invertible_"


def _solver_options(petsc: dict[str, str | None]) -> dict[str, str | None]:
    """Options for the solver (prefix removed); others go to PETSc's database unchanged."""
    from petsc4py import PETSc

    ours = {}
    for name, value in petsc.items():
        if name.startswith(_PREFIX):
            ours[name[len(_PREFIX) :]] = value
        else:
            PETSc.Options().setValue(name, value if value is not None else "")
    return ours


def _check_combination(parameters, petsc: dict[str, str | None], comm) -> None:
    line_search = petsc.get(f"{_PREFIX}snes_linesearch_type")
    if parameters.extension == "ife" and line_search not in (None, "l2", "basic"):
        raise ValueError(
            f"the ife extension has no energy, so the energy line search {line_search!r} cannot "
            "work with it: leave the line search to the solver (l2 on the residual) or use c1/c2"
        )
    if parameters.extension != "none" and parameters.model != "neo-hookean" and comm.rank == 0:
        print(
            f"note: {parameters.model} is defined through inversion without an extension; "
            f"{parameters.extension} still replaces its energy below the threshold",
            file=sys.stderr,
        )


def _print_summary(summary: dict, output: Path) -> None:
    keys = ("outcome", "steps", "final_inverted", "max_inverted", "final_min_J")
    shown = ", ".join(f"{key} {summary.get(key)}" for key in keys if key in summary)
    extra = [key for key in ("rest_distance", "tip_displacement") if key in summary]
    for key in extra:
        shown += f", {key} {summary[key]:.6g}"
    shown += f", Newton {summary['newton_iterations']['total']}, {summary['wall_time_s']:.1f} s"
    print(f"{summary['scene']}: {shown}")
    if summary.get("reason"):
        print(f"{summary['scene']}: {summary['reason']}")
    cut_out = summary.get("failed_stage") not in (None, "NaN")
    if cut_out and (output / "checkpoint.npz").exists():
        more = summary["parameters"]["max_cuts"] + 4
        print(
            f"{summary['scene']}: to go on from t = {summary['time']:.6g} s with smaller steps: "
            f"dolfinx-invertible run {summary['scene']} --resume {output} --max-cuts {more}"
        )
    print(f"wrote {output}/ ({summary['scene']}.xdmf, {summary['scene']}.jsonl, summary.json)")


def _report(arguments: argparse.Namespace) -> int:
    module = importlib.import_module(f"dolfinx_invertible.reports.{arguments.report_module}")
    _quiet_libraries(getattr(arguments, "verbose", False))
    return module.command(arguments)


def parser() -> argparse.ArgumentParser:
    """Return the argument parser of the whole command line."""
    from dolfinx_invertible.reports import REPORTS
    from dolfinx_invertible.scenes import SCENES, get_scene

    top = argparse.ArgumentParser(
        prog="dolfinx-invertible",
        description="Invertible hyperelasticity for DOLFINx (Stomakhin et al. 2012).",
    )
    commands = top.add_subparsers(dest="command", required=True, metavar="COMMAND")

    commands.add_parser(
        "list", help="list the scenes", description="List every scene with its paper figure."
    ).set_defaults(handler=_list)

    run_parser = commands.add_parser(
        "run",
        help="run a scene",
        description="Run a scene; PETSc options (e.g. -dolfinx_invertible_snes_monitor) may "
        "follow the scene's options.",
    )
    scenes = run_parser.add_subparsers(dest="scene", required=True, metavar="SCENE")
    for name in SCENES:
        scene = get_scene(name)
        # argparse %-formats help texts; a description's "20 % of" is text.
        described = f"{scene.description} [{scene.figure}]".replace("%", "%%")
        scene_parser = scenes.add_parser(
            name,
            help=described,
            description=f"{described}. Options not given take this scene's defaults, shown below.",
        )
        _scene_options(scene_parser, scene)
        scene_parser.set_defaults(handler=_run)

    report_parser = commands.add_parser("report", help="write a report", description="Reports.")
    reports = report_parser.add_subparsers(dest="report", required=True, metavar="NAME")
    for name, description in REPORTS.items():
        module_name = name.replace("-", "_")
        module = importlib.import_module(f"dolfinx_invertible.reports.{module_name}")
        if not hasattr(module, "add_arguments"):
            continue
        described = description.replace("%", "%%")
        subparser = reports.add_parser(name, help=described, description=described)
        module.add_arguments(subparser)
        subparser.set_defaults(handler=_report, report_module=module_name)

    compile_parser = commands.add_parser(
        "compile",
        help="compile the cell kernels into numba's disk cache",
        description=(
            "Compile the DOLFINx cell kernels of the default materials (2D and 3D) into "
            "numba's disk cache."
        ),
    )
    compile_parser.set_defaults(handler=_compile)

    benchmarks = _benchmarks()
    bench_parser = commands.add_parser(
        "bench",
        help="run a benchmark",
        description="Benchmarks; each prints a table and JSON.",
        # Outside a checkout every bench command line, --help included, gets the one error.
        add_help=benchmarks is not None,
    )
    if benchmarks is None:
        bench_parser.add_argument("arguments", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
        bench_parser.set_defaults(handler=_no_benchmarks)
    else:
        benchmarks.add_arguments(bench_parser)
    return top


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the process exit code.

    Parameters
    ----------
    argv
        Arguments after the program name; defaults to ``sys.argv[1:]``.
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    top = parser()
    arguments, extra = top.parse_known_args(argv)
    if arguments.command == "run":
        arguments.petsc = extra
    elif extra and arguments.handler is not _no_benchmarks:
        top.error(f"unrecognized arguments: {' '.join(extra)}")
    if arguments.command == "bench":
        arguments.bench_argv = argv[argv.index("bench") + 1 :]
    return arguments.handler(arguments)
