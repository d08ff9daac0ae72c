"""Checkpoints of a run: Functions and a JSON state in one file, readable on any rank count.

A checkpoint is one NumPy ``.npz`` file that rank 0 writes under a temporary name and renames
into place, so a run killed at any instant leaves the previous checkpoint or the new one, never
half of one. It holds, for every Function, the coordinates of its degrees-of-freedom nodes and
their values, gathered from all ranks, and the caller's state as JSON. Where the ranks must not
communicate, each writes its own part (:func:`write_checkpoint_part`), and the parts are read
together.

Nodes are matched by their coordinates when a checkpoint is read, so a run may continue on
another number of ranks (another partition, another local numbering) and on any supported
DOLFINx: the mesh only has to be the same, which a reader checks (every node found, within
10⁻¹⁰ of the mesh's extent). Lagrange spaces have one node per point, so the match is unique.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np

__all__ = [
    "CheckpointError",
    "owned_nodes",
    "read_checkpoint",
    "read_state",
    "write_checkpoint",
    "write_checkpoint_part",
]

#: Coordinates are matched after rounding to this fraction of the mesh's extent.
MATCH_TOLERANCE = 1e-10


class CheckpointError(ValueError):
    """A checkpoint that is missing, unreadable or made on another mesh."""


def owned_nodes(function) -> tuple[np.ndarray, np.ndarray]:
    """Return the coordinates (n, 3) and values (n, block) of the rank's owned nodes (views)."""
    space = function.function_space
    owned = space.dofmap.index_map.size_local
    block = space.dofmap.index_map_bs
    coordinates = space.tabulate_dof_coordinates()[:owned]
    values = function.x.array[: owned * block].reshape(owned, block)
    return coordinates, values


def write_checkpoint(
    path: str | Path, functions: Mapping[str, Any], state: Mapping[str, Any], comm
) -> int:
    """Write the Functions and the JSON-able ``state`` to ``path`` (collective).

    Returns the file's size in bytes (on every rank).
    """
    path = Path(path)
    gathered = {}
    for name, function in functions.items():
        coordinates, values = owned_nodes(function)
        parts = comm.gather((coordinates, values), root=0)
        if comm.rank == 0:
            gathered[f"{name}.coordinates"] = np.concatenate([part[0] for part in parts])
            gathered[f"{name}.values"] = np.concatenate([part[1] for part in parts])
    size = 0
    error = None
    if comm.rank == 0:
        try:
            temporary = path.with_name(f".{path.name}.tmp")
            with open(temporary, "wb") as file:
                np.savez(file, state=np.array(json.dumps(dict(state))), **gathered)
                file.flush()
                os.fsync(file.fileno())
            os.replace(temporary, path)
            size = path.stat().st_size
        except OSError as exception:
            error = f"cannot write the checkpoint {path}: {exception}"
    error = comm.bcast(error, root=0)
    if error is not None:
        raise OSError(error)
    return comm.bcast(size, root=0)


def write_checkpoint_part(
    path: str | Path,
    nodes: Mapping[str, tuple[np.ndarray, np.ndarray]],
    state: Mapping[str, Any],
    *,
    sync: bool = True,
) -> int:
    """Write one rank's share of a checkpoint, with no communication; return its bytes.

    ``nodes`` maps a field's name to the coordinates and values of the rank's owned nodes
    (:func:`owned_nodes`). :func:`read_checkpoint` reads the parts of all ranks together.
    Written under a temporary name and renamed into place, like a whole checkpoint; ``sync``
    also waits for the disk (a killed process loses nothing either way, a crashed machine may).
    """
    path = Path(path)
    arrays = {}
    for name, (coordinates, values) in nodes.items():
        arrays[f"{name}.coordinates"] = coordinates
        arrays[f"{name}.values"] = values
    temporary = path.with_name(f".{path.name}.tmp")
    with open(temporary, "wb") as file:
        np.savez(file, state=np.array(json.dumps(dict(state))), **arrays)
        if sync:
            file.flush()
            os.fsync(file.fileno())
    os.replace(temporary, path)
    return path.stat().st_size


def read_state(path: str | Path) -> dict[str, Any]:
    """Return the JSON state of a checkpoint (any rank, no communication)."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"no checkpoint at {path}")
    try:
        with np.load(path) as data:
            return json.loads(str(data["state"]))
    except (OSError, ValueError, KeyError) as error:
        raise CheckpointError(f"cannot read the checkpoint {path}: {error}") from None


def read_checkpoint(
    path: str | Path | Sequence[str | Path], functions: Mapping[str, Any], comm
) -> dict[str, Any]:
    """Set the Functions from a checkpoint; return its state (collective).

    ``path`` is one file (:func:`write_checkpoint`) or the parts of all ranks
    (:func:`write_checkpoint_part`), read together; the state is the first file's.

    Raises
    ------
    CheckpointError
        On every rank: a file is missing or unreadable, lacks a Function, or a node of this
        mesh is not in it (another mesh, degree or size).
    """
    paths = [Path(path)] if isinstance(path, (str, Path)) else [Path(p) for p in path]
    error = None
    try:
        state = read_state(paths[0])
        for name, function in functions.items():
            stored, values = [], []
            for part in paths:
                with np.load(part) as data:
                    if f"{name}.coordinates" not in data:
                        raise CheckpointError(f"the checkpoint {part} has no field {name!r}")
                    stored.append(data[f"{name}.coordinates"])
                    values.append(data[f"{name}.values"])
            _set_from(function, name, np.concatenate(stored), np.concatenate(values), paths[0])
    except (CheckpointError, OSError, ValueError) as exception:
        error = str(exception)
    errors = comm.allgather(error)
    message = next((message for message in errors if message is not None), None)
    if message is not None:
        raise CheckpointError(message)
    return state


def _set_from(function, name: str, stored: np.ndarray, values: np.ndarray, path: Path) -> None:
    space = function.function_space
    coordinates = space.tabulate_dof_coordinates()
    block = space.dofmap.index_map_bs
    if values.shape[1:] != (block,) or stored.shape[1:] != coordinates.shape[1:]:
        raise CheckpointError(f"the checkpoint {path} holds {name!r} in another space")
    mesh = space.mesh
    extent = np.ptp(mesh.geometry.x, axis=0).max() if len(mesh.geometry.x) else 1.0
    extent = mesh.comm.allreduce(extent, op=MPI.MAX)
    quantum = MATCH_TOLERANCE * extent
    source = _match(np.rint(stored / quantum), np.rint(coordinates / quantum))
    missing = np.flatnonzero(source < 0)
    if len(missing):
        first = coordinates[missing[0]]
        raise CheckpointError(
            f"the checkpoint {path} was made on another mesh: no {name!r} node at "
            f"({', '.join(f'{value:.6g}' for value in first)})"
        )
    array = function.x.array.reshape(-1, block)
    array[:] = values[source]
    function.x.scatter_forward()


def _match(stored: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Return, for each row of ``wanted``, the index of the equal row of ``stored`` (or −1).

    Rows of ``stored`` are distinct, and so are those of ``wanted``: after sorting both
    together, an equal pair is two neighbours, one from each.
    """
    rows = np.vstack([stored, wanted])
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    same = np.flatnonzero(np.all(ordered[1:] == ordered[:-1], axis=1))
    first, second = order[same], order[same + 1]
    from_stored = np.where(first < len(stored), first, second)
    from_wanted = np.where(first < len(stored), second, first) - len(stored)
    source = np.full(len(wanted), -1, dtype=np.int64)
    source[from_wanted] = from_stored
    return source
