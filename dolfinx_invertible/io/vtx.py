"""Time-series output as ADIOS2 VTX files: the displacement at full order, per-cell diagnostics.

``VTXResultWriter("run.bp", u)`` writes, next to each other:

``run.bp``
    The displacement in its own Lagrange space: a P2 field at its P2 nodes, not interpolated
    onto the vertices as XDMF stores it. DOLFINx's ``VTXWriter`` (ADIOS2 BP4), the format
    DOLFINx recommends for time series; ParaView opens it with its ADIOS2 VTX reader.
``run-cells.bp``
    One DG0 field per diagnostic (a VTX file holds one element type).
``run.jsonl``
    The step log, when the writer is asked to keep it (``log_path``), as :class:`~dolfinx_
    invertible.io.xdmf.ResultWriter` keeps it.

Needs DOLFINx built with ADIOS2 (:data:`~dolfinx_invertible._compat.VTX_AVAILABLE`: DOLFINx
0.9 on Debian trixie and the 0.11 wheel are, Debian bookworm's 0.5.2 is not). Unlike the XDMF
series, a VTX file is written by ADIOS2 until it is closed: a run killed before that may leave
it unreadable.
"""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import dolfinx.fem
import numpy as np

from dolfinx_invertible import _compat
from dolfinx_invertible.io.step_log import StepLog

__all__ = ["VTX_AVAILABLE", "VTXResultWriter"]

#: Whether this DOLFINx writes VTX files (built with ADIOS2).
VTX_AVAILABLE = _compat.VTX_AVAILABLE


class VTXResultWriter:
    """Writes the displacement and per-cell diagnostics as VTX files (collective).

    Parameters
    ----------
    path
        The displacement's ``.bp`` folder; the diagnostics go to ``<stem>-cells.bp``. Both are
        overwritten.
    u
        The displacement Function, in the space it is written in.
    log_path
        Also keep the JSON-lines step log there (when no XDMF writer keeps it).

    Raises
    ------
    ValueError
        If this DOLFINx cannot write VTX files, or ``path`` does not end in ``.bp``.
    """

    def __init__(self, path: str | Path, u, *, log_path: str | Path | None = None):
        if not _compat.VTX_AVAILABLE:
            raise ValueError(
                f"VTX output needs DOLFINx built with ADIOS2; DOLFINx {dolfinx.__version__} "
                "here is not (Debian bookworm's 0.5.2): use --format xdmf"
            )
        self.path = Path(path)
        if self.path.suffix != ".bp":
            raise ValueError(f"path must end in .bp, got {str(path)!r}")
        self.cells_path = self.path.with_name(f"{self.path.stem}-cells.bp")
        self.comm = u.function_space.mesh.comm
        if self.comm.rank == 0:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            for folder in (self.path, self.cells_path):
                shutil.rmtree(folder, ignore_errors=True)
        self.comm.barrier()
        self._displacement = dolfinx.fem.Function(u.function_space, name="displacement")
        self._writer = _compat.vtx_writer(self.comm, self.path, [self._displacement])
        mesh = u.function_space.mesh
        self._cell_space = _compat.scalar_function_space(mesh, 0, "DG")
        owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self._owned_cell_dofs = _compat.cell_dofs(self._cell_space)[:owned, 0]
        self._cell_fields: dict[str, dolfinx.fem.Function] = {}
        self._cell_writer = None
        self._log = StepLog(log_path, self.comm) if log_path is not None else None
        self.steps_written = 0

    def write(
        self,
        t: float,
        u,
        diagnostics: Mapping[str, np.ndarray] | None = None,
        record: Mapping[str, Any] | None = None,
    ) -> None:
        """Append one time step: ``u`` at full order, each diagnostic as a DG0 field."""
        line = self._log.format(self.steps_written, t, record) if self._log is not None else None
        self._displacement.x.array[:] = u.x.array
        self._writer.write(float(t))
        if diagnostics:
            if self._cell_writer is None:
                for name in diagnostics:
                    self._cell_fields[name] = dolfinx.fem.Function(self._cell_space, name=name)
                self._cell_writer = _compat.vtx_writer(
                    self.comm, self.cells_path, list(self._cell_fields.values())
                )
            for name, function in self._cell_fields.items():
                function.x.array[self._owned_cell_dofs] = diagnostics[name]
                function.x.scatter_forward()
            self._cell_writer.write(float(t))
        self.steps_written += 1
        if self._log is not None:
            self._log.append(line)

    def close(self) -> None:
        """Close the files (ADIOS2 finishes them here)."""
        for writer in (self._writer, self._cell_writer):
            if writer is not None:
                writer.close()
        self._writer = self._cell_writer = None
        if self._log is not None:
            self._log.close()

    def __enter__(self) -> VTXResultWriter:
        return self

    def __exit__(self, *exception) -> None:
        self.close()
