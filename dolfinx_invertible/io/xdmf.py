"""Time-series output: displacement and per-cell diagnostics in XDMF, a JSON-lines step log.

File layout
-----------
``ResultWriter("run.xdmf", mesh)`` produces, next to each other:

``run.xdmf``
    One XDMF 3 time series: the mesh grid, followed by a single temporal collection with one
    grid per :meth:`ResultWriter.write` call. Each of these grids includes the mesh topology and
    geometry by ``xi:include``, carries its ``<Time Value=...>`` and holds every field of that
    step: the displacement at the mesh nodes and one cell-centred attribute per diagnostic.
    ParaView's XDMF3 reader and ``meshio.xdmf.TimeSeriesReader`` both read it as one dataset
    with all fields per time step.
``run.h5``
    The mesh (topology and geometry), written once when the writer starts.
``run.steps/000000.h5``, ``run.steps/000001.h5``, ...
    The fields of each step, one HDF5 file per step, numbered like the ``step`` of the log.
    ``run.xdmf`` refers to them by paths relative to its folder, so the three belong together:
    copying a run means copying its folder.
``run.jsonl``
    One JSON object per step (``step``, ``time`` and the caller's record), written by rank 0
    and flushed line by line.

Why every step has its own HDF5 file
------------------------------------
HDF5 updates a file's metadata (free-space lists, the superblock) in place while it closes
the file; a run killed at that moment can leave the file unreadable as a whole. So no file that
``run.xdmf`` refers to is ever opened for writing again: ``run.h5`` is written once, and each
step goes to a new file that ``run.xdmf`` only refers to once it is closed. A kill can damage
only the file of the step in flight, which no reader is pointed at.

How a step is written
---------------------
DOLFINx's ``XDMFFile`` writes the heavy data (in parallel, through HDF5), but it puts each
Function in a temporal collection of its own; readers that take one collection (meshio) then see
a single field, and ParaView shows the fields as separate blocks. It also wants a mesh grid in
the same XML to refer to (without one it warns, and the XML it writes points nowhere). So for
step 3, say, rank 0 first writes the working file ``run.steps/000003.xdmf-partial`` holding only
the mesh grid of ``run.xdmf`` (its data in ``../run.h5``) and an empty ``run.steps/000003.h5``;
every rank opens the pair in append mode, DOLFINx writes the Functions, and closes it. Rank
0 then moves the new attributes, exactly as DOLFINx wrote them but with their HDF5 paths made
relative to ``run.xdmf``, into one grid of the single collection, puts the result in place as
``run.xdmf`` with an atomic rename, and removes the working file: a reader (or a run killed at
any instant) sees every completed step and nothing half-written.

Why the files are closed after every step
-----------------------------------------
While a DOLFINx ``XDMFFile`` is open it holds the HDF5 file with its data possibly unflushed
and locked (HDF5 file locking refuses every other reader, ParaView included). So every step's
file is closed before :meth:`ResultWriter.write` returns: every step written is on disk and
readable, also while the run goes on and after it fails.

When a writer starts it removes the step folder of a previous run of the same name, so no file
in it is left from another run.
"""

from __future__ import annotations

import copy
import math
import os
import posixpath
import re
import shutil
import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from mpi4py import MPI

import dolfinx.fem
import numpy as np

from dolfinx_invertible import _compat
from dolfinx_invertible.io.step_log import StepLog

__all__ = ["DISPLACEMENT_NAME", "SERIES_NAME", "STEPS_SUFFIX", "WORKING_SUFFIX", "ResultWriter"]

#: Name of the displacement attribute in the XDMF file.
DISPLACEMENT_NAME = "displacement"
#: Name of the temporal collection grid that holds the steps.
SERIES_NAME = "time_series"
#: Suffix of the XML files DOLFINx writes to (the mesh's and the step in flight's); each is
#: removed once its content is in the series, and any left over by ``close``.
WORKING_SUFFIX = ".xdmf-partial"
#: Suffix of the folder next to the XDMF file that holds the HDF5 file of every step.
STEPS_SUFFIX = ".steps"

_XINCLUDE_NAMESPACE = _compat.XDMF_XINCLUDE_NAMESPACE
_XINCLUDE = f"{{{_XINCLUDE_NAMESPACE}}}include"
_XML_HEADER = '<?xml version="1.0"?>\n<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
# Names end up in XPath queries and HDF5 paths (/Function/<name>/<time>): no quotes or slashes.
_VALID_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]*\Z")
_RESERVED_FIELDS = (DISPLACEMENT_NAME, SERIES_NAME)

ElementTree.register_namespace("xi", _XINCLUDE_NAMESPACE)


class ResultWriter:
    """Writes a displacement field and per-cell diagnostics as one XDMF time series.

    A context manager; all methods are collective on ``comm``. Every :meth:`write` leaves the
    XDMF file and its HDF5 files complete and closed, so the steps written so far stay readable
    if the run fails later, even if it is killed (see the module docstring).

    Parameters
    ----------
    path
        The ``.xdmf`` file; the mesh goes next to it with the suffix ``.h5``, and the fields of
        each step to its own HDF5 file in the folder with the suffix ``.steps`` (``run.xdmf``:
        ``run.h5`` and ``run.steps/000000.h5``, ...). All are overwritten (a previous step
        folder is removed); missing parent directories are created.
    mesh
        The mesh, written once.
    comm
        The communicator; ``None`` means ``mesh.comm``, and any other must be congruent to it.
    log_path
        The JSON-lines step log; ``None`` means ``path`` with the suffix ``.jsonl``.
    log
        Keep the step log (the ``record`` of every :meth:`write`); ``False`` writes none (a
        scene run keeps its log apart, :class:`~dolfinx_invertible.scenes.outputs.StepLogOutput`).
    resume
        ``(steps, time)``: continue the series of a run that was stopped, after its first
        ``steps`` steps, the last of them at ``time``; the steps after them are dropped from
        the XDMF file, the step folder and the log. The continued steps refer to a copy of the
        mesh written now (``run.steps/mesh-NNNNNN.h5``, numbered by the first step that uses
        it), since a run continued on another number of ranks numbers its nodes differently.

    Examples
    --------
    >>> with ResultWriter("output/run.xdmf", mesh) as writer:
    ...     for t in times:
    ...         diagnostics = cell_diagnostics(u, material)
    ...         writer.write(t, u, diagnostics, record=summary(diagnostics, mesh.comm))
    """

    def __init__(
        self,
        path: str | Path,
        mesh,
        *,
        comm: MPI.Comm | None = None,
        log_path: str | Path | None = None,
        resume: tuple[int, float] | None = None,
        log: bool = True,
    ):
        self.path = Path(path)
        if self.path.suffix != ".xdmf":
            raise ValueError(f"path must end in .xdmf, got {str(path)!r}")
        self.log_path = self.path.with_suffix(".jsonl") if log_path is None else Path(log_path)
        self._working_path = self.path.with_suffix(WORKING_SUFFIX)
        self.steps_folder = self.path.with_suffix(STEPS_SUFFIX)
        self.mesh = mesh
        self.comm = mesh.comm if comm is None else comm
        if MPI.Comm.Compare(self.comm, mesh.comm) not in (MPI.IDENT, MPI.CONGRUENT):
            raise ValueError("comm must be the mesh's communicator (or congruent to it)")
        self.steps_written = 0 if resume is None else int(resume[0])
        self._last_time = -math.inf if resume is None else float(resume[1])
        self._closed = False
        #: The mesh grid the steps refer to explicitly (a resumed run), or None: the series'.
        self._mesh_grid = None

        self._cell_dimension = mesh.topology.dim
        self._num_owned_cells = mesh.topology.index_map(self._cell_dimension).size_local
        # XDMF stores nodal fields at the geometry nodes, so the displacement is interpolated
        # into the Lagrange space of the coordinate element whatever the degree of u.
        self._displacement = dolfinx.fem.Function(
            _compat.vector_function_space(
                mesh, _compat.coordinate_element_degree(mesh), "Lagrange"
            ),
            name=DISPLACEMENT_NAME,
        )
        self._cell_space = _compat.scalar_function_space(mesh, 0, "DG")
        self._owned_cell_dofs = _compat.cell_dofs(self._cell_space)[: self._num_owned_cells, 0]
        self._cell_fields: dict[str, dolfinx.fem.Function] = {}

        if resume is None:
            prepare, mesh_xml = self._prepare_folders, self._working_path
        else:
            prepare = self._truncate_series
            mesh_xml = self.steps_folder / f"mesh-{self.steps_written:06d}{WORKING_SUFFIX}"
        self._on_rank_0(prepare, OSError, f"cannot prepare the output of {self.path}")
        try:
            with _compat.xdmf_file(self.comm, mesh_xml, "w") as xdmf:
                xdmf.write_mesh(mesh)
        except RuntimeError as error:
            raise ValueError(
                f"cannot create {mesh_xml.with_suffix('.h5')}: {error} (is another process "
                "writing it or holding it open? HDF5 locks the files it writes)"
            ) from None
        self._step_template = None
        if resume is None:
            self._on_rank_0(self._publish_mesh, RuntimeError, f"could not write {self.path}")
        else:
            self._on_rank_0(
                lambda: self._adopt_mesh(mesh_xml), RuntimeError, f"could not write {mesh_xml}"
            )
        self._log = (
            StepLog(self.log_path, self.comm, keep=None if resume is None else self.steps_written)
            if log
            else None
        )

    def __enter__(self) -> ResultWriter:
        return self

    def __exit__(self, exception_type, exception, traceback) -> None:
        self.close()

    def close(self) -> None:
        """Close the step log. The XDMF file is already complete after every :meth:`write`."""
        if self._closed:
            return
        self._closed = True
        if self._log is not None:
            self._log.close()
        if self.comm.rank == 0:
            self._working_path.unlink(missing_ok=True)
            # A step whose write failed: its files, if any, are not part of the series.
            for file in self._step_files(self.steps_written):
                file.unlink(missing_ok=True)

    def write(
        self,
        t: float,
        u: dolfinx.fem.Function,
        diagnostics: Mapping[str, np.ndarray] | None = None,
        record: Mapping[str, Any] | None = None,
    ) -> None:
        """Append one time step: ``u``, each diagnostic as a DG0 field, and a log line.

        Parameters
        ----------
        t
            Time (or load factor) of the step; finite and larger than that of the previous step.
        u
            Displacement, a vector Function on the writer's mesh (any Lagrange degree: it is
            interpolated to the nodes of the mesh).
        diagnostics
            Per-cell values, e.g. from :func:`~dolfinx_invertible.fem.diagnostics.cell_diagnostics`:
            each a 1-D array with one value per locally owned cell, in local cell order. Each
            key becomes a cell attribute of that name. Every rank must pass the same keys.
        record
            Extra fields of the log line (energy, iteration counts, wall time, ...): JSON
            values, numpy scalars or arrays. Non-finite numbers are logged as null. Only rank
            0's record is written.

        Raises
        ------
        ValueError
            On every rank, if any rank has a bad argument: a diagnostic of the wrong length or
            shape (the message names the key), differing keys across ranks, a reserved or
            invalid name, a time not after the previous one, or a record that is not JSON.
        RuntimeError
            If the writer is closed.
        """
        if self._closed:
            raise RuntimeError(f"ResultWriter for {self.path} is closed")
        error = None
        try:
            values = self._checked_diagnostics(diagnostics)
            t = float(t)
            if not math.isfinite(t) or t <= self._last_time:
                raise ValueError(
                    f"t must be finite and greater than the previous time {self._last_time}, "
                    f"got {t}"
                )
            line = None if self._log is None else self._log.format(self.steps_written, t, record)
            self._check_displacement(u)
        except (ValueError, TypeError) as exception:
            error = str(exception)
        # Agreed on by all ranks first: one rank raising alone would hang the others in the
        # collective HDF5 writes below.
        errors = self.comm.allgather(error)
        if any(message is not None for message in errors):
            rank, message = next((r, m) for r, m in enumerate(errors) if m is not None)
            raise ValueError(message if rank == self.comm.rank else f"rank {rank}: {message}")
        keys = self.comm.allgather(list(values))
        if any(other != keys[0] for other in keys):
            raise ValueError(f"the diagnostics keys differ between ranks: {keys}")

        self._displacement.interpolate(u)
        functions = [self._displacement]
        for name, cell_values in values.items():
            function = self._cell_field(name)
            function.x.array[self._owned_cell_dofs] = cell_values
            function.x.scatter_forward()
            functions.append(function)
        step_xml, _ = self._step_files(self.steps_written)
        # Also orders the working file before every rank opens it.
        self._on_rank_0(self._prepare_step, RuntimeError, f"could not create {step_xml}")
        with _compat.xdmf_file(self.comm, step_xml, "a") as xdmf:
            for function in functions:
                xdmf.write_function(function, float(t))
        self._merge_step_into_series()

        self._last_time = float(t)
        self.steps_written += 1
        if self._log is not None:
            self._log.append(line)

    def _checked_diagnostics(self, diagnostics) -> dict[str, np.ndarray]:
        if diagnostics is None:
            return {}
        values = {}
        for name, given in diagnostics.items():
            if not isinstance(name, str) or not _VALID_NAME.match(name):
                raise ValueError(
                    f"diagnostic name {name!r} must be a string of letters, digits, '_', '.' or "
                    "'-' that starts with a letter or '_'"
                )
            if name in _RESERVED_FIELDS:
                raise ValueError(f"diagnostic name {name!r} is reserved by the writer")
            array = np.asarray(given, dtype=np.float64)
            if array.shape != (self._num_owned_cells,):
                raise ValueError(
                    f"diagnostic {name!r} must have one value per locally owned cell, shape "
                    f"({self._num_owned_cells},), got shape {array.shape}"
                )
            values[name] = array
        return values

    def _check_displacement(self, u) -> None:
        expected = (self.mesh.geometry.dim,)
        if not isinstance(u, dolfinx.fem.Function) or u.ufl_shape != expected:
            raise ValueError(f"u must be a Function with value shape {expected}, got {u!r}")

    def _cell_field(self, name: str) -> dolfinx.fem.Function:
        if name not in self._cell_fields:
            self._cell_fields[name] = dolfinx.fem.Function(self._cell_space, name=name)
        return self._cell_fields[name]

    def _step_files(self, index: int) -> tuple[Path, Path]:
        """Return the working XML of step ``index`` and its HDF5 file (named so by DOLFINx)."""
        xml = self.steps_folder / f"{index:06d}{WORKING_SUFFIX}"
        return xml, xml.with_suffix(".h5")

    def _merge_step_into_series(self) -> None:
        step_xml, _ = self._step_files(self.steps_written)
        self._on_rank_0(
            lambda: _merge_step(step_xml, self.path, self._mesh_grid),
            RuntimeError,
            f"could not rewrite {self.path}",
        )

    def _on_rank_0(self, action, error_type: type[Exception], failure: str) -> None:
        """Run ``action`` on rank 0; if it fails, raise ``error_type`` on every rank.

        Also a barrier: no rank returns before rank 0 is done.
        """
        error = cause = None
        if self.comm.rank == 0:
            try:
                action()
            except Exception as exception:  # re-raised on every rank below
                error, cause = f"{failure}: {exception!r}", exception
        error = self.comm.bcast(error, root=0)
        if error is not None:
            raise error_type(error) from cause

    def _prepare_folders(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        # A previous run's steps, which would otherwise be taken for this run's.
        if self.steps_folder.is_dir() and not self.steps_folder.is_symlink():
            shutil.rmtree(self.steps_folder)
        else:
            self.steps_folder.unlink(missing_ok=True)

    def _truncate_series(self) -> None:
        if not self.path.is_file():
            raise OSError(f"{self.path} does not exist: nothing to continue")
        tree = ElementTree.parse(self.path)
        series = _series(tree.getroot().find("Domain"))
        steps = [] if series is None else series.findall("Grid")
        if len(steps) < self.steps_written:
            raise OSError(
                f"{self.path} holds {len(steps)} steps, fewer than the {self.steps_written} to "
                "continue after"
            )
        for step in steps[self.steps_written :]:
            series.remove(step)
        _write_series(tree, self.path)
        self.steps_folder.mkdir(exist_ok=True)
        # Files of steps after the ones kept (and of the meshes only those used).
        for file in self.steps_folder.iterdir():
            number = re.match(r"(?:mesh-)?(\d{6})\.", file.name)
            if number is not None and int(number.group(1)) >= self.steps_written:
                file.unlink()

    def _adopt_mesh(self, mesh_xml: Path) -> None:
        text = mesh_xml.read_text(encoding="utf-8")
        self._step_template = _step_template(text, ".")
        grid = ElementTree.fromstring(text).find("Domain/Grid")
        folder = os.path.relpath(self.steps_folder, self.path.parent).replace(os.sep, "/")
        for item in grid.iter("DataItem"):
            item.text = _rebased(item.text, folder)
        self._mesh_grid = grid
        mesh_xml.unlink()

    def _publish_mesh(self) -> None:
        # DOLFINx's own file (the mesh grid) as it is, until the first step is merged into it.
        text = self._working_path.read_text(encoding="utf-8")
        _replace_atomically(self.path, text)
        self._working_path.unlink()
        self._step_template = _step_template(text, "..")

    def _prepare_step(self) -> None:
        step_xml, _ = self._step_files(self.steps_written)
        self.steps_folder.mkdir(exist_ok=True)
        # An empty HDF5 file (emptied, if a failed attempt at this step left one): in append
        # mode each rank of DOLFINx opens the file if it exists and creates it if not, so it
        # must exist before any rank looks, or the ranks may make different collective calls.
        with _compat.xdmf_file(MPI.COMM_SELF, step_xml, "w"):
            pass
        step_xml.write_text(self._step_template, encoding="utf-8")


def _step_template(mesh_text: str, folder: str) -> str:
    """Return the XML a step starts from: the mesh grid of ``mesh_text``, seen from a step file.

    ``write_function`` refers to the first uniform grid of its file for the topology and the
    geometry (and warns if there is none); this one points at the series' mesh data, in
    ``folder`` relative to the step folder.
    """
    root = ElementTree.fromstring(mesh_text)
    grid = root.find("Domain/Grid")
    for item in grid.iter("DataItem"):
        item.text = _rebased(item.text, folder)
    ElementTree.indent(grid, space="  ", level=2)
    return (
        f'{_XML_HEADER}<Xdmf Version="{root.get("Version", "3.0")}" '
        f'xmlns:xi="{_XINCLUDE_NAMESPACE}">\n  <Domain>\n    '
        f"{ElementTree.tostring(grid, encoding='unicode').rstrip()}\n  </Domain>\n</Xdmf>\n"
    )


def _rebased(reference: str, folder: str) -> str:
    """Return a DataItem's HDF5 reference ``file:/dataset`` with ``file`` seen from ``folder``."""
    file, dataset = reference.strip().rsplit(":", 1)
    return f"{posixpath.normpath(posixpath.join(folder, file))}:{dataset}"


def _series(domain) -> ElementTree.Element | None:
    return next(
        (
            grid
            for grid in domain.findall("Grid")
            if grid.get("GridType") == "Collection" and grid.get("Name") == SERIES_NAME
        ),
        None,
    )


def _merge_step(step_xml: Path, path: Path, mesh_grid=None) -> None:
    """Fold the per-Function collections DOLFINx wrote in ``step_xml`` into one step of ``path``.

    DOLFINx wrote one temporal collection per Function, each with the one grid of this step.
    Their attributes go into one new grid of the series, with their HDF5 references (relative
    to ``step_xml``) made relative to ``path``; the series replaces ``path`` atomically, and
    ``step_xml`` is removed. The step refers to the series' mesh, or holds the topology and
    geometry of ``mesh_grid`` (references relative to ``path``) if one is given.
    """
    new_grids = [
        grid
        for collection in ElementTree.parse(step_xml).getroot().find("Domain").findall("Grid")
        if collection.get("GridType") == "Collection"
        for grid in collection.findall("Grid")
    ]
    if not new_grids:
        raise RuntimeError(f"DOLFINx wrote no Function to {step_xml}")
    tree = ElementTree.parse(path)
    domain = tree.getroot().find("Domain")
    series = _series(domain)
    if series is None:
        series = ElementTree.SubElement(
            domain, "Grid", Name=SERIES_NAME, GridType="Collection", CollectionType="Temporal"
        )
    step = ElementTree.SubElement(series, "Grid", Name=SERIES_NAME, GridType="Uniform")
    # All fields of one step share the mesh and time: take the first grid's references. The
    # XInclude points at the first uniform grid of its document, which in ``path`` is the mesh.
    if mesh_grid is None:
        step.append(new_grids[0].find(_XINCLUDE))
    else:
        step.extend(copy.deepcopy(mesh_grid.find(part)) for part in ("Topology", "Geometry"))
    step.append(new_grids[0].find("Time"))
    folder = os.path.relpath(step_xml.parent, path.parent).replace(os.sep, "/")
    for grid in new_grids:
        for attribute in grid.findall("Attribute"):
            for item in attribute.iter("DataItem"):
                if item.get("Format") == "HDF":
                    item.text = _rebased(item.text, folder)
            step.append(attribute)

    # XDMF reads a data item without a precision as single precision (ParaView does); ours
    # are doubles.
    for item in domain.iter("DataItem"):
        if "NumberType" not in item.attrib:
            item.set("NumberType", "Float")
            item.set("Precision", "8")
    _write_series(tree, path)
    step_xml.unlink()


def _write_series(tree, path: Path) -> None:
    ElementTree.indent(tree, space="  ")
    # The prefix map is global: another library (meshio) may have bound "xi" to the other
    # XInclude URI.
    ElementTree.register_namespace("xi", _XINCLUDE_NAMESPACE)
    text = _XML_HEADER + ElementTree.tostring(tree.getroot(), encoding="unicode") + "\n"
    _replace_atomically(path, text)


def _replace_atomically(path: Path, text: str) -> None:
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(text, encoding="utf-8")
    # Atomic on POSIX: a reader sees the previous file or this one, never half of it.
    os.replace(temporary, path)
