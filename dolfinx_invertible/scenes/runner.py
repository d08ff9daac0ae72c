"""Run a scene: build it from its declaration, step it, write its output and its summary.

The output of a run in its directory (``results/SCENE/`` by default):

- ``SCENE.xdmf`` + ``SCENE.h5`` + ``SCENE.steps/``: the displacement and the per-cell diagnostics
  of every completed step (the XML, the mesh, one HDF5 file per step), readable while the run
  goes on and after it stops (also after SIGKILL, up to the last completed step);
- ``SCENE.jsonl``: one line per completed step (time, energy, iterations, inverted cells, ...);
- ``summary.json``: every parameter used and how the run went, written at the end, also after a
  failure or an interrupt (``completed`` false and the reason given); the previous run's summary
  is removed when a run starts, so a summary never belongs to another run;
- ``checkpoint.npz`` (dynamic scenes, with ``checkpoint_every``): the state to continue from
  (:mod:`.checkpoints`), and ``checkpoint-part-G-R-of-N.npz``, each rank's part of the state
  after each of the last two steps;
- scene-specific extras (e.g. ``trajectories.npy``).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
from collections.abc import Callable, Sequence
from pathlib import Path
from time import perf_counter
from typing import Any

from mpi4py import MPI

import dolfinx
import numpy as np

from dolfinx_invertible.fem.diagnostics import cell_diagnostics, summary
from dolfinx_invertible.fem.spaces import vector_function_space
from dolfinx_invertible.io.step_log import json_ready
from dolfinx_invertible.io.vtx import VTX_AVAILABLE, VTXResultWriter
from dolfinx_invertible.io.xdmf import ResultWriter
from dolfinx_invertible.scenes.checkpoints import (
    StepParts,
    check_resumable,
    restore_run,
    write_run_checkpoint,
)
from dolfinx_invertible.scenes.observer import RunObserver
from dolfinx_invertible.scenes.outcome import relaxation_outcome, rest_distance
from dolfinx_invertible.scenes.parameters import (
    OUTPUT_FORMATS,
    PROJECT_CHOICES,
    Parameters,
    make_material,
)
from dolfinx_invertible.scenes.run import Run
from dolfinx_invertible.scenes.scene import Scene
from dolfinx_invertible.solvers.dynamics import ImplicitDynamics
from dolfinx_invertible.solvers.hyperelastic import HyperelasticProblem
from dolfinx_invertible.solvers.monitors import NewtonIteration, StepAttempt, StepCap
from dolfinx_invertible.solvers.results import SolverError, SolveResult
from dolfinx_invertible.solvers.stepping import StepController, solve_load_steps

__all__ = ["RunInterrupted", "check_output_directory", "run_scene"]


class RunInterrupted(BaseException):  # noqa: N818 (an interruption, not an error)
    """Raised inside a run by SIGINT or SIGTERM, so that the summary still gets written.

    A :class:`BaseException`, like :class:`KeyboardInterrupt`: handlers of ``Exception`` (e.g.
    around a file rewrite) must not turn it into an error.
    """


def check_output_directory(path: Path, comm) -> None:
    """Create ``path`` and make sure files can be written there; clear error otherwise."""
    error = None
    if comm.rank == 0:
        try:
            path.mkdir(parents=True, exist_ok=True)
            probe = path / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as exception:
            error = (
                f"cannot write to the output directory {path}: {exception.strerror or exception}"
            )
    error = comm.bcast(error, root=0)
    if error is not None:
        raise ValueError(error)


def _damping_coefficient(scene: Scene, parameters: Parameters) -> float:
    """Return the mass-proportional damping c [1/s] for the requested fraction ζ.

    ζ is relative to critical damping of the lowest elastic mode, ω ≈ π c / L: c = 2 ζ ω.
    """
    if parameters.damping == 0.0:
        return 0.0
    lowest = math.pi * parameters.wave_speed / parameters.size
    return 2.0 * parameters.damping * lowest


def _write_json(path: Path, data: dict) -> None:
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
    os.replace(temporary, path)


class _Signals:
    """Turn SIGINT and SIGTERM into :class:`RunInterrupted` while a run is stepping.

    Inside :meth:`deferred` (writing a step) a signal is held until the block ends, so every
    step in the output is complete.
    """

    def __enter__(self):
        self._previous = {}
        self._held: int | None = None
        self._deferring = False
        for number in (signal.SIGINT, signal.SIGTERM):
            try:
                self._previous[number] = signal.signal(number, self._received)
            except ValueError:  # not the main thread
                pass
        return self

    def _received(self, number, frame):
        if self._deferring:
            self._held = number
        else:
            self._raise(number)

    @staticmethod
    def _raise(number):
        raise RunInterrupted(f"interrupted by {signal.Signals(number).name}")

    @contextlib.contextmanager
    def deferred(self):
        self._deferring = True
        try:
            yield
        finally:
            self._deferring = False
        if self._held is not None:
            self._raise(self._held)

    def __exit__(self, *exception):
        for number, handler in self._previous.items():
            signal.signal(number, handler)


class _Progress:
    """A tqdm progress bar on rank 0 (none when quiet)."""

    def __init__(self, enabled: bool, total: float, unit: str):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(
                total=total, unit=unit, dynamic_ncols=True, leave=True,
                bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} {unit} [{elapsed}<{remaining}] "
                "{postfix}",
            )  # fmt: skip

    def update(self, time_now: float, **postfix) -> None:
        if self.bar is not None:
            self.bar.update(time_now - self.bar.n)
            self.bar.set_postfix(postfix, refresh=False)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_scene(
    scene_class: type[Scene],
    parameters: Parameters,
    *,
    output: Path | None = None,
    quiet: bool = True,
    petsc_options: dict[str, Any] | None = None,
    comm=MPI.COMM_WORLD,
    on_step: Callable[[Run], None] | None = None,
    observers: Sequence[RunObserver] = (),
    problem_options: dict[str, Any] | None = None,
    checkpoint_every: int | None = None,
    resume: bool = False,
    output_format: str = "xdmf",
) -> dict[str, Any]:
    """Run a scene; return its summary (written to ``output/summary.json`` too).

    Parameters
    ----------
    scene_class
        The scene.
    parameters
        Every parameter, the scene's defaults already filled in; validated here.
    output
        Directory of the XDMF, the step log and the summary; ``None`` writes nothing (used by
        the reports, which only read the summaries).
    quiet
        No progress bar.
    petsc_options
        Solver options (without prefix), e.g. from the command line.
    comm
        The communicator.
    on_step
        Called with the :class:`Run` after every completed step.
    observers
        :class:`~dolfinx_invertible.scenes.observer.RunObserver` instances whose hooks see the
        run: its start, every Newton iteration, step cap and attempt, every step and its end.
    problem_options
        Options of the problem that override the scene's and the parameters' (e.g.
        ``{"linear_solver": "iterative", "blend_after": 0}``; see
        :class:`~dolfinx_invertible.HyperelasticProblem`).
    checkpoint_every
        Dynamic scenes with an ``output``: write ``checkpoint.npz`` there every this many
        steps and after the last one (see :mod:`.checkpoints`); ``None``: no checkpoints.
    resume
        Continue the stopped run in ``output`` from its checkpoint (same scene and parameters;
        ``t_end`` may be later), appending to its XDMF file and step log.
    output_format
        ``"xdmf"`` (:class:`~dolfinx_invertible.io.xdmf.ResultWriter`), ``"vtx"``
        (:class:`~dolfinx_invertible.io.vtx.VTXResultWriter`: the displacement at full
        order; needs DOLFINx with ADIOS2) or ``"both"``.

    Raises
    ------
    ValueError
        Invalid parameters or output directory: before anything is computed.
    """
    parameters.validate()
    scene_class.check_parameters(parameters)
    if checkpoint_every is not None and (
        int(checkpoint_every) != checkpoint_every or checkpoint_every < 1
    ):
        raise ValueError(f"--checkpoint-every must be an integer >= 1, got {checkpoint_every!r}")
    if output_format not in OUTPUT_FORMATS:
        raise ValueError(
            f"--format must be one of {', '.join(OUTPUT_FORMATS)}, got {output_format!r}"
        )
    if output_format != "xdmf" and not VTX_AVAILABLE:
        raise ValueError(
            f"--format {output_format}: VTX output needs DOLFINx built with ADIOS2, and "
            f"DOLFINx {dolfinx.__version__} here is not: use --format xdmf"
        )
    if resume and output_format != "xdmf":
        raise ValueError(
            "--resume continues the XDMF series and the step log; VTX files are not appended "
            "to: use --format xdmf"
        )
    checkpoint_state = None
    if resume:
        if not scene_class.dynamic:
            raise ValueError(
                f"--resume: {scene_class.name} is quasi-static; only dynamic scenes write "
                "checkpoints"
            )
        if output is None:
            raise ValueError("--resume needs the output directory of the run")
        checkpoint_state = check_resumable(
            output, scene_class.name, parameters, timed_by_end=scene_class.timed_by_end
        )
    if output is not None:
        check_output_directory(output, comm)
        if comm.rank == 0:
            (output / "summary.json").unlink(missing_ok=True)
    scene = scene_class(parameters, comm)
    material = make_material(parameters)
    mesh = scene.mesh = scene.create_mesh()
    space = vector_function_space(mesh, parameters.degree)
    u = dolfinx.fem.Function(space, name="displacement")
    initial = scene.initial_displacement()
    if initial is not None:
        u.interpolate(initial)
        u.x.scatter_forward()
    bcs, boundary_update = scene.boundary_conditions(space)
    body_contact = scene.body_contact(u)
    if body_contact is not None:
        boundary_update = _starting_steps_of(body_contact, boundary_update)
    options = dict(scene.problem_options())
    options.setdefault("project", PROJECT_CHOICES[parameters.project])
    options.setdefault("petsc_options", petsc_options)
    if parameters.inversion_free is not None:
        options.setdefault("inversion_free", parameters.inversion_free)
    options.setdefault("elastic", parameters.elastic)
    options.setdefault("linear_solver", parameters.linear_solver)
    options.setdefault("pc", parameters.pc)
    options.setdefault("globalization", parameters.globalization)
    options.update(problem_options or {})
    terms, limits = scene.terms(u), scene.step_limits(u)
    if body_contact is not None:
        # The barrier is undefined on crossing surfaces: refuse them before the first step.
        body_contact.check_intersection_free()
        terms, limits = [*terms, body_contact], [*limits, body_contact.step_limit()]
    if terms:
        options.setdefault("terms", terms)
    if limits:
        options.setdefault("step_limits", limits)
    run = Run(
        scene=scene,
        parameters=parameters,
        material=material,
        mesh=mesh,
        u=u,
        body_contact=body_contact,
    )
    if scene.dynamic:
        velocity = None
        initial_velocity = scene.initial_velocity()
        if initial_velocity is not None:
            velocity = dolfinx.fem.Function(space)
            velocity.interpolate(initial_velocity)
            velocity.x.scatter_forward()
        options.setdefault("max_cuts", int(parameters.max_cuts))
        run.dynamics = ImplicitDynamics(
            u,
            material,
            density=parameters.density,
            dt=parameters.dt,
            bcs=bcs,
            velocity=velocity,
            gravity=scene.gravity(),
            external_energy=scene.external_energy(u),
            boundary_update=boundary_update,
            scheme=parameters.scheme,
            damping=_damping_coefficient(scene, parameters),
            **options,
        )
        run.controller = run.dynamics.controller
    else:
        run.problem = HyperelasticProblem(
            u, material, bcs, external_energy=scene.external_energy(u), **options
        )
        run.controller = StepController(1.0 / parameters.steps, max_cuts=int(parameters.max_cuts))
    observers = list(observers)
    on_attempt = _watch(run, observers) if observers else None
    if checkpoint_state is not None:
        restore_run(run, output)
    checkpoints = checkpoint_every if scene.dynamic and output is not None else None
    parts = StepParts(output, comm.rank, comm.size) if checkpoints is not None else None
    writers: list = []
    if output is not None and output_format in ("xdmf", "both"):
        writers.append(
            ResultWriter(
                output / f"{scene.name}.xdmf",
                mesh,
                resume=None
                if checkpoint_state is None
                else (checkpoint_state["steps_written"], run.time),
            )
        )
    if output is not None and output_format in ("vtx", "both"):
        # The step log goes with the XDMF series, or with the VTX files if there is none.
        log = None if writers else output / f"{scene.name}.jsonl"
        writers.append(VTXResultWriter(output / f"{scene.name}.bp", u, log_path=log))
    dofs = space.dofmap.index_map.size_global * space.dofmap.index_map_bs
    total = parameters.stop_time if scene.dynamic else 1.0
    progress = _Progress(not quiet and comm.rank == 0, total, "s" if scene.dynamic else "load")
    failure: dict[str, Any] = {}
    completed = False
    try:
        with _Signals() as signals:
            if checkpoint_state is None:
                with signals.deferred():
                    _record(run, writers, None)
                scene.record(run)
            for observer in observers:
                observer.start(run)

            def step_done(t: float, result: SolveResult) -> None:
                run.time = t
                run.result = result
                with signals.deferred():
                    _record(run, writers, result)
                scene.record(run)
                if checkpoints is not None:
                    with signals.deferred():
                        if run.steps % checkpoints == 0:
                            write_run_checkpoint(run, output, writers[0].steps_written)
                        parts.write(run, writers[0].steps_written)
                progress.update(
                    t, newton=result.newton_iterations, inverted=run.diagnostics["inverted_cells"]
                )
                if on_step is not None:
                    on_step(run)
                for observer in observers:
                    observer.step(run)

            if run.dynamics is not None:
                run.dynamics.advance(parameters.stop_time, on_step=step_done)
                if checkpoints is not None and run.steps % checkpoints != 0:
                    with signals.deferred():
                        write_run_checkpoint(run, output, writers[0].steps_written)
            else:
                solve_load_steps(
                    run.problem,
                    scene.set_load,
                    parameters.steps,
                    on_step=step_done,
                    controller=run.controller,
                    on_attempt=on_attempt,
                )
            completed = True
    except SolverError as error:
        if checkpoints is not None and (run.steps % checkpoints != 0 or run.steps == 0):
            # The state is the last completed step's (or the initial one) and the step
            # controller's cuts so far: --resume continues the cuts from there.
            write_run_checkpoint(run, output, writers[0].steps_written)
        failure = {
            "reason": str(error),
            "failed_stage": error.stage,
            "failed_time": error.time_tried,
        }
        run.nan_encountered = run.nan_encountered or error.stage == "NaN"
    except RunInterrupted as interrupt:
        progress.close()
        for writer in writers:
            writer.close()
        # Ranks may be interrupted at different points: no collective operation from here on.
        summary_data = _summary(run, dofs, completed=False, converged=True, final=None)
        summary_data.update(reason=str(interrupt), interrupted=True)
        if output is not None and comm.rank == 0:
            _write_json(output / "summary.json", summary_data)
        raise
    finally:
        progress.close()
        for writer in writers:
            writer.close()
    for observer in observers:
        observer.end(run)
    final = summary(cell_diagnostics(u, material), comm)
    summary_data = _summary(run, dofs, completed=completed, converged=not failure, final=final)
    summary_data.update(failure)
    if scene.relaxation:
        distance = rest_distance(u)
        outcome = relaxation_outcome(
            completed, failure.get("failed_stage"), final["inverted_cells"], distance
        )
        summary_data.update(
            rest_distance=distance,
            recovered=outcome == "recovered",
            outcome=outcome,
            kinetic_energy_final=run.kinetic_energy,
        )
    else:
        outcome = (
            "completed"
            if completed
            else ("nan" if failure.get("failed_stage") == "NaN" else "failed")
        )
        summary_data["outcome"] = outcome
    summary_data.update(scene.quantities(run))
    if output is not None and comm.rank == 0:
        for name, data in scene.files(run).items():
            np.save(output / name, np.asarray(data))
        _write_json(output / "summary.json", json_ready(summary_data))
    return json_ready(summary_data)


def _starting_steps_of(contact, update: Callable[[float], None] | None) -> Callable[[float], None]:
    """Return the scene's boundary update followed by the contact's start of the step."""

    def starting(t: float) -> None:
        if update is not None:
            update(t)
        contact.set_time(t)

    return starting


def _watch(run: Run, observers: list[RunObserver]) -> Callable[[StepAttempt], None]:
    """Connect the observers to the run's solver; return the callback of step attempts."""

    def on_iteration(record: NewtonIteration) -> None:
        for observer in observers:
            observer.iteration(run, record)

    def on_step_cap(cap: StepCap) -> None:
        for observer in observers:
            observer.step_cap(run, cap)

    def on_attempt(attempt: StepAttempt) -> None:
        for observer in observers:
            observer.attempt(run, attempt)

    if run.dynamics is not None:
        run.dynamics.add_monitor(
            on_iteration=on_iteration, on_step_cap=on_step_cap, on_attempt=on_attempt
        )
    else:
        run.problem.add_monitor(on_iteration=on_iteration, on_step_cap=on_step_cap)
    return on_attempt


def _record(run: Run, writers: Sequence[Any], result: SolveResult | None) -> None:
    """Diagnostics of the current state into the run's statistics, the XDMF and the log."""
    diagnostics = cell_diagnostics(run.u, run.material)
    record = summary(diagnostics, run.mesh.comm)
    run.diagnostics = record
    run.max_inverted = max(run.max_inverted, record["inverted_cells"])
    run.min_J = min(run.min_J, record["min_J"])
    if result is not None:
        run.steps += 1
        run.newton_total += result.newton_iterations
        run.newton_max = max(run.newton_max, result.newton_iterations)
        run.linear_total += result.linear_iterations
        for kind, share in result.svd_share.items():
            if share is not None:
                run.svd_points.setdefault(kind, []).append(share)
        if result.energy is not None and not math.isfinite(result.energy):
            run.nan_encountered = True
        record.update(
            energy=result.energy,
            newton_iterations=result.newton_iterations,
            linear_iterations=result.linear_iterations,
            tangent=result.tangent,
            svd_share=result.svd_share,
        )
        record["step_size"] = run.controller.accepted[-1]
    if run.dynamics is not None:
        record["kinetic_energy"] = run.dynamics.kinetic_energy
    if run.body_contact is not None:
        distance = run.body_contact.minimum_distance()
        crossing = run.body_contact.intersections()
        run.min_distance = min(run.min_distance, distance)
        run.intersections += crossing
        record.update(min_distance=distance, intersections=crossing)
    record["wall_time"] = perf_counter() - run.started
    for writer in writers:
        # A strictly increasing time for the initial state of a quasi-static run too.
        writer.write(run.time, run.u, diagnostics, record)


def _summary(
    run: Run, dofs: int, *, completed: bool, converged: bool, final: dict | None
) -> dict[str, Any]:
    parameters = run.parameters
    stepping = run.controller.statistics() if run.controller is not None else {}
    last = final if final is not None else run.diagnostics
    svd_share = {kind: float(np.mean(values)) for kind, values in run.svd_points.items() if values}
    contact = (
        {}
        if run.body_contact is None
        else {"min_distance": run.min_distance, "intersections": run.intersections}
    )
    minimizer = run.minimizer
    return {
        "scene": run.scene.name,
        "model": parameters.model,
        "extension": parameters.extension,
        "parameters": parameters.as_dict(),
        # What the "auto" choices of the parameters became.
        "solver": {
            "linear_solver": minimizer.linear_solver,
            "globalization": minimizer.globalization,
        },
        "ranks": run.mesh.comm.size,
        "dofs": dofs,
        "steps": run.steps,
        "time": run.time,
        "completed": completed,
        "converged": converged,
        "nan_encountered": run.nan_encountered,
        "final_min_J": last.get("min_J"),
        "final_inverted": last.get("inverted_cells"),
        "max_inverted": max(run.max_inverted, last.get("inverted_cells", 0) or 0),
        "min_J_reached": run.min_J,
        "newton_iterations": {"total": run.newton_total, "max": run.newton_max},
        "linear_iterations": run.linear_total,
        "wall_time_s": perf_counter() - run.started,
        "svd_share": svd_share,
        "stepping": stepping,
        **contact,
    }
