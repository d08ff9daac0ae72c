"""Time-series output: displacement and per-cell diagnostics in XDMF, a JSON-lines step log.

File layout
-----------
``ResultWriter("run.xdmf", mesh)`` produces three files:

``run.xdmf`` and ``run.h5``
    One XDMF 3 time series: the mesh grid, written once, followed by a single temporal
    collection with one grid per :meth:`ResultWriter.write` call. Each of these grids includes
    the mesh topology and geometry by ``xi:include``, carries its ``<Time Value=...>`` and holds
    every field of that step: the displacement at the mesh nodes and one cell-centred attribute
    per diagnostic. ParaView's XDMF3 reader and ``meshio.xdmf.TimeSeriesReader`` both read it as
    one dataset with all fields per time step.
``run.jsonl``
    One JSON object per step (``step``, ``time`` and the caller's record), written by rank 0
    and flushed line by line.

Why the XML is rewritten
------------------------
DOLFINx's ``XDMFFile`` writes the heavy data (in parallel, through HDF5), but it puts each
Function in a temporal collection of its own; readers that take one collection (meshio) then see
a single field, and ParaView shows the fields as separate blocks. After each step rank 0 moves
the new attributes, exactly as DOLFINx wrote them, into the one collection.

Why DOLFINx writes to a working copy
------------------------------------
DOLFINx rewrites the XML in place when it appends; a run killed at that moment would leave
``run.xdmf`` holding the unmerged collections of the step in flight. So DOLFINx works on
``run.xdmf-partial`` (same HDF5 file, whose name DOLFINx derives by replacing the suffix), and
rank 0 puts each merged XML in place as ``run.xdmf`` with an atomic rename: a reader (or a run
killed at any instant) sees every completed step and nothing half-written. :meth:`close`
removes the working copy.

Why the file is closed after every step
---------------------------------------
While a DOLFINx ``XDMFFile`` is open it holds the HDF5 file with its data possibly unflushed
and locked (HDF5 file locking refuses every other reader, ParaView included). So each
:meth:`ResultWriter.write` opens the file in append mode, writes, and closes it again: every
step written is on disk and readable, also while the run goes on and after it fails.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ElementTree
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from mpi4py import MPI

import dolfinx.fem
import numpy as np

from dolfinx_invertible import _compat
from dolfinx_invertible.io.step_log import StepLog

__all__ = ["DISPLACEMENT_NAME", "SERIES_NAME", "WORKING_SUFFIX", "ResultWriter"]

#: Name of the displacement attribute in the XDMF file.
DISPLACEMENT_NAME = "displacement"
#: Name of the temporal collection grid that holds the steps.
SERIES_NAME = "time_series"
#: Suffix of the XML file DOLFINx appends to while a run writes (removed by ``close``).
WORKING_SUFFIX = ".xdmf-partial"

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
    XDMF/HDF5 pair complete and closed, so the steps written so far stay readable if the run
    fails later (see the module docstring).

    Parameters
    ----------
    path
        The ``.xdmf`` file; the HDF5 data goes next to it with the suffix ``.h5``. Both are
        overwritten; missing parent directories are created.
    mesh
        The mesh, written once.
    comm
        The communicator; ``None`` means ``mesh.comm``, and any other must be congruent to it.
    log_path
        The JSON-lines step log; ``None`` means ``path`` with the suffix ``.jsonl``.

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
    ):
        self.path = Path(path)
        if self.path.suffix != ".xdmf":
            raise ValueError(f"path must end in .xdmf, got {str(path)!r}")
        self.log_path = self.path.with_suffix(".jsonl") if log_path is None else Path(log_path)
        self._working_path = self.path.with_suffix(WORKING_SUFFIX)
        self.mesh = mesh
        self.comm = mesh.comm if comm is None else comm
        if MPI.Comm.Compare(self.comm, mesh.comm) not in (MPI.IDENT, MPI.CONGRUENT):
            raise ValueError("comm must be the mesh's communicator (or congruent to it)")
        self.steps_written = 0
        self._last_time = -math.inf
        self._closed = False

        self._cell_dimension = mesh.topology.dim
        self._num_owned_cells = mesh.topology.index_map(self._cell_dimension).size_local
        # XDMF stores nodal fields at the geometry nodes, so the displacement is interpolated
        # into the Lagrange space of the coordinate element whatever the degree of u.
        self._displacement = dolfinx.fem.Function(
            _compat.vector_function_space(
                mesh, "Lagrange", _compat.coordinate_element_degree(mesh)
            ),
            name=DISPLACEMENT_NAME,
        )
        self._cell_space = _compat.scalar_function_space(mesh, "DG", 0)
        self._owned_cell_dofs = _compat.cell_dofs(self._cell_space)[: self._num_owned_cells, 0]
        self._cell_fields: dict[str, dolfinx.fem.Function] = {}

        if self.comm.rank == 0:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.log_path.parent.mkdir(parents=True, exist_ok=True)
        self.comm.barrier()
        try:
            with _compat.xdmf_file(self.comm, self._working_path, "w") as xdmf:
                xdmf.write_mesh(mesh)
        except RuntimeError as error:
            raise ValueError(
                f"cannot create {self.path.with_suffix('.h5')}: {error} (is another process "
                "writing it or holding it open? HDF5 locks the files it writes)"
            ) from None
        if self.comm.rank == 0:
            # DOLFINx's own file as it is: a rewrite would drop its XInclude namespace
            # declaration, which its later appends rely on.
            _replace_atomically(self.path, self._working_path.read_text(encoding="utf-8"))
        self.comm.barrier()
        self._log = StepLog(self.log_path, self.comm)

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
            line = self._log.format(self.steps_written, t, record)
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
        with _compat.xdmf_file(self.comm, self._working_path, "a") as xdmf:
            for function in functions:
                xdmf.write_function(function, float(t))
        self._merge_step_into_series()

        self._last_time = float(t)
        self.steps_written += 1
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

    def _merge_step_into_series(self) -> None:
        error = None
        if self.comm.rank == 0:
            try:
                _merge_new_collections(self._working_path, self.path)
            except Exception as exception:  # re-raised on every rank below
                error = f"could not rewrite {self.path}: {exception!r}"
        # Also orders the rewrite before the next append, where every rank reads the XML.
        error = self.comm.bcast(error, root=0)
        if error is not None:
            raise RuntimeError(error)


def _merge_new_collections(working: Path, path: Path) -> None:
    """Fold the per-Function collections DOLFINx just wrote into one step of the series.

    DOLFINx appends one temporal collection per Function name that is not found in ``working``;
    since earlier steps were already moved out of them, each holds exactly the one new grid.
    The result goes back to ``working`` (for DOLFINx's next append) and, atomically, to
    ``path``.
    """
    tree = ElementTree.parse(working)
    domain = tree.getroot().find("Domain")
    series = None
    new_grids = []
    for grid in domain.findall("Grid"):
        if grid.get("GridType") != "Collection":
            continue
        if grid.get("Name") == SERIES_NAME:
            series = grid
        else:
            new_grids.extend(grid.findall("Grid"))
            domain.remove(grid)
    if not new_grids:
        return
    if series is None:
        series = ElementTree.SubElement(
            domain, "Grid", Name=SERIES_NAME, GridType="Collection", CollectionType="Temporal"
        )
    step = ElementTree.SubElement(series, "Grid", Name=SERIES_NAME, GridType="Uniform")
    # All fields of one step share the mesh and time: take the first grid's references.
    step.append(new_grids[0].find(_XINCLUDE))
    step.append(new_grids[0].find("Time"))
    for grid in new_grids:
        for attribute in grid.findall("Attribute"):
            step.append(attribute)

    # XDMF reads a data item without a precision as single precision (ParaView does); ours
    # are doubles.
    for item in domain.iter("DataItem"):
        if "NumberType" not in item.attrib:
            item.set("NumberType", "Float")
            item.set("Precision", "8")
    ElementTree.indent(tree, space="  ")
    # The prefix map is global: another library (meshio) may have bound "xi" to the other
    # XInclude URI, which would make DOLFINx's next "xi:include" an unbound prefix.
    ElementTree.register_namespace("xi", _XINCLUDE_NAMESPACE)
    text = _XML_HEADER + ElementTree.tostring(tree.getroot(), encoding="unicode") + "\n"
    working.write_text(text, encoding="utf-8")
    _replace_atomically(path, text)


def _replace_atomically(path: Path, text: str) -> None:
    temporary = path.with_name(f".{path.name}.tmp")
    temporary.write_text(text, encoding="utf-8")
    # Atomic on POSIX: a reader sees the previous file or this one, never half of it.
    os.replace(temporary, path)
