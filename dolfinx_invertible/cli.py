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
import dataclasses
import importlib
import importlib.util
import logging
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from dolfinx_invertible.choices import OUTPUT_FORMATS

__all__ = ["RUN_OPTIONS", "load_package", "main", "option_table", "parser"]


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


def load_package(name: str, folder: Path):
    """Import the package in ``folder`` as ``name`` by its path, whatever else is on sys.path.

    The one loader of the benchmarks: the command line finds them next to the package, and
    ``python path/to/benchmarks`` loads its own folder, so that no other ``benchmarks`` on
    ``sys.path`` stands in for them. One already loaded (``python -m benchmarks``, the tests)
    is returned as it is.
    """
    loaded = sys.modules.get(name)
    if loaded is not None:
        return loaded
    specification = importlib.util.spec_from_file_location(
        name, folder / "__init__.py", submodule_search_locations=[str(folder)]
    )
    package = importlib.util.module_from_spec(specification)
    sys.modules[name] = package
    specification.loader.exec_module(package)
    return package


def _benchmarks():
    """Return the ``benchmarks`` package of the source checkout of this package, or None.

    The benchmarks are not installed: in a checkout they sit beside the package directory, at
    the repository root (with ``pyproject.toml``).
    """
    if "benchmarks" in sys.modules:
        return sys.modules["benchmarks"]
    root = Path(__file__).resolve().parent.parent
    folder = root / "benchmarks"
    if not ((folder / "__init__.py").is_file() and (root / "pyproject.toml").is_file()):
        return None
    return load_package("benchmarks", folder)


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
    """Add a scene's options to its parser: the parameters that apply to it, then the run's."""
    from dolfinx_invertible.scenes.parameters import OPTION_GROUPS, Parameters

    groups = {name: subparser.add_argument_group(name) for name in OPTION_GROUPS}
    defaults = Parameters(**scene.defaults)
    for field in dataclasses.fields(Parameters):
        option = _parameter_option(field, scene, getattr(defaults, field.name))
        if option is not None:
            group, name, settings = option
            groups[group].add_argument(name, dest=field.name, **settings)
    _run_options(subparser, scene)


def _parameter_option(field, scene, default) -> tuple[str, str, dict] | None:
    """Return (group, option, add_argument settings) of a parameter for ``scene``, or None."""
    from dolfinx_invertible.scenes.parameters import (
        SCENE_KINDS,
        option_name,
        options_of,
        shown_default,
    )

    metadata = options_of(field, dynamic=scene.dynamic)
    if metadata is None:
        return None
    # argparse %-formats help texts; a help's "20 % of" is text.
    help_text = metadata["help"].replace("{default}", shown_default(default)).replace("%", "%%")
    settings: dict[str, Any] = {"help": help_text}
    kind = metadata["scenes"]
    if kind == "scene-choices":
        values = scene.choices.get(field.name)
        if field.name == "mesh" and scene.takes_mesh_file:
            names = " | ".join(values or ())
            settings["metavar"] = f"{{{names}}}|PATH" if names else "PATH"
            settings["help"] = (
                "the body: a gmsh .msh or XDMF mesh file of straight tetrahedra, fitted into the "
                "box the scene's own body fills (--resolution does not apply)"
                + (f", or one of {names} (default: {default})" if names else "")
            )
        elif values is None:
            return None
        else:
            settings.update(choices=list(values), type=type(values[0]))
    elif not SCENE_KINDS[kind][1](scene):
        return None
    elif metadata["flag"]:
        settings.update(action="store_const", const=True)
    elif metadata["choices"] is not None:
        settings["choices"] = list(metadata["choices"])
    else:
        settings.update(type=_argument_type(field), metavar=metadata["metavar"])
    return metadata["group"], option_name(field), settings


def _argument_type(field) -> type:
    """Return the type argparse converts an option's value to (int, float or str)."""
    annotation = str(field.type)
    return int if annotation.startswith("int") else float if "float" in annotation else str


#: The options of a run that are not parameters: (option, add_argument settings).
RUN_OPTIONS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("--petsc-option", dict(action="append", default=[], metavar="NAME=VALUE",
     dest="petsc_option", help="a PETSc option of the solver, without prefix or dash, e.g. "
     "ksp_rtol=1e-8 or snes_monitor= (repeatable; -NAME VALUE with the dolfinx_invertible_ "
     "prefix works too); checked before the run, and named at its end if no solver read it")),
    ("--out", dict(type=Path, metavar="DIR", help="output directory (default: results/SCENE)")),
    ("--quiet", dict(action="store_true", help="no progress bar")),
    ("--verbose", dict(action="store_true", help="show compiler and solver chatter (FFCx, "
     "cffi, numba warnings) and Python tracebacks")),
    ("--format", dict(choices=list(OUTPUT_FORMATS), default="xdmf", dest="output_format",
     help="what the run writes (default: xdmf): " + "; ".join(
         f"{name}, {choice.description}" for name, choice in OUTPUT_FORMATS.items()))),
    ("--checkpoint-every", dict(type=int, metavar="N", default=10, dest="checkpoint_every",
     help="write DIR/CHECKPOINT every N steps and after the last one, to --resume "
     "from (0: never; default: 10)")),
    ("--resume", dict(type=Path, metavar="DIR", help="continue the stopped run in DIR from its "
     "checkpoint, with its own parameters (--t-end may be later, --max-cuts may change), "
     "appending to its output")),
)  # fmt: skip


def _run_options(subparser: argparse.ArgumentParser, scene) -> None:
    """Add the options of a run (:data:`RUN_OPTIONS`) as the group "output"."""
    group = subparser.add_argument_group("output")
    for name, settings in RUN_OPTIONS:
        group.add_argument(name, **{**settings, "help": _run_help(settings, scene.name)})


def _run_help(settings: dict[str, Any], scene: str) -> str:
    from dolfinx_invertible.scenes.checkpoints import CHECKPOINT_NAME

    text = settings["help"].replace("SCENE", scene).replace("CHECKPOINT", CHECKPOINT_NAME)
    return text.replace("%", "%%")


def option_table() -> str:
    """Return the Markdown table of every option of ``run SCENE`` (docs/scenes.md)."""
    from dolfinx_invertible.scenes.parameters import option_table as parameter_table

    rows = []
    for name, settings in RUN_OPTIONS:
        value = settings.get("metavar")
        if "choices" in settings:
            value = "{" + ",".join(settings["choices"]) + "}"
        shown = f"`{name}{'' if value is None else ' ' + value}`"
        rows.append(f"| {shown} | every scene | {_run_help(settings, 'SCENE')} |")
    return "\n".join([parameter_table(), *rows])


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
    resume = arguments.resume
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
        from dolfinx_invertible.solvers.petsc_options import (
            check_petsc_options,
            unused_petsc_options,
        )

        solver_options = {
            name[len(_PREFIX) :]: value for name, value in petsc.items() if name.startswith(_PREFIX)
        }
        check_petsc_options(solver_options, prefix=_PREFIX)
        summary = run_scene(
            scene,
            parameters,
            output=output,
            quiet=arguments.quiet or comm.rank != 0,
            petsc_options=_solver_options(petsc),
            comm=comm,
            checkpoint_every=arguments.checkpoint_every or None,
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
    unused = unused_petsc_options(solver_options, prefix=_PREFIX, comm=comm)
    if comm.rank == 0:
        _print_summary(summary, output)
        if unused:
            print(
                f"warning: no solver read the PETSc option {', '.join(unused)} (misspelt, or "
                "not one this run's solvers take): it had no effect",
                file=sys.stderr,
            )
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
    from dolfinx_invertible.scenes.checkpoints import CHECKPOINT_NAME

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
    if cut_out and (output / CHECKPOINT_NAME).exists():
        more = summary["parameters"]["max_cuts"] + 4
        print(
            f"{summary['scene']}: to go on from t = {summary['time']:.6g} s with smaller steps: "
            f"dolfinx-invertible run {summary['scene']} --resume {output} --max-cuts {more}"
        )
    print(f"wrote {output}/ ({summary['scene']}.xdmf, {summary['scene']}.jsonl, summary.json)")


def _paraview(arguments: argparse.Namespace) -> int:
    from dolfinx_invertible.scenes import pictures

    return pictures.command(arguments)


def _report(arguments: argparse.Namespace) -> int:
    module = importlib.import_module(f"dolfinx_invertible.reports.{arguments.report_module}")
    _quiet_libraries(getattr(arguments, "verbose", False))
    return module.command(arguments)


def parser() -> argparse.ArgumentParser:
    """Return the argument parser of the whole command line."""
    top = argparse.ArgumentParser(
        prog="dolfinx-invertible",
        description="Invertible hyperelasticity for DOLFINx (Stomakhin et al. 2012).",
    )
    commands = top.add_subparsers(dest="command", required=True, metavar="COMMAND")
    commands.add_parser(
        "list", help="list the scenes", description="List every scene with its paper figure."
    ).set_defaults(handler=_list)
    _add_run(commands)
    _add_reports(commands)
    paraview_parser = commands.add_parser(
        "paraview",
        help="read or render a run's XDMF series with ParaView (pvbatch)",
        description="Read or render ResultWriter XDMF series with ParaView (pvbatch).",
    )
    from dolfinx_invertible.scenes import pictures

    pictures.add_arguments(paraview_parser)
    paraview_parser.set_defaults(handler=_paraview)
    commands.add_parser(
        "compile",
        help="compile the cell kernels into numba's disk cache",
        description="Compile the DOLFINx cell kernels of the default materials (2D and 3D) "
        "into numba's disk cache.",
    ).set_defaults(handler=_compile)
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


def _add_run(commands) -> None:
    """Add ``run SCENE [options]``, one parser per scene with its defaults."""
    from dolfinx_invertible.scenes import SCENES, get_scene

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


def _add_reports(commands) -> None:
    """Add ``report NAME [options]``, one parser per report."""
    from dolfinx_invertible.reports import REPORTS

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
