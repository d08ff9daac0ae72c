"""The JSON-lines step log: one JSON object per step, written by rank 0 and flushed per line."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from mpi4py import MPI

import numpy as np

__all__ = ["RESERVED_RECORD_KEYS", "StepLog", "json_ready", "json_value"]

#: Keys the log writes itself.
RESERVED_RECORD_KEYS = ("step", "time")


class StepLog:
    """A JSON-lines file: one object per step, ``step`` and ``time`` first, then the record.

    Only rank 0 of ``comm`` opens and writes the file; every rank may format lines (so that all
    ranks agree on whether a record is valid before a collective write).

    Parameters
    ----------
    path
        The ``.jsonl`` file; overwritten, unless ``keep`` is given.
    comm
        The communicator whose rank 0 writes.
    keep
        Continue the file after its first ``keep`` lines (a resumed run), dropping the rest.
    """

    def __init__(self, path: str | Path, comm: MPI.Comm, *, keep: int | None = None):
        self.path = Path(path)
        self._stream = None
        if comm.rank == 0:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            mode = "w"
            if keep is not None and self.path.exists():
                kept = self.path.read_text(encoding="utf-8").splitlines(keepends=True)[:keep]
                temporary = self.path.with_name(f".{self.path.name}.tmp")
                temporary.write_text("".join(kept), encoding="utf-8")
                os.replace(temporary, self.path)
                mode = "a"
            # Line buffered: each record reaches the file as soon as it is written.
            self._stream = open(self.path, mode, buffering=1, encoding="utf-8")

    @staticmethod
    def format(step: int, t: float, record: Mapping[str, Any] | None) -> str:
        """Return the JSON line of one step; ``ValueError``/``TypeError`` for a bad record."""
        record = {} if record is None else dict(record)
        clashing = [key for key in RESERVED_RECORD_KEYS if key in record]
        if clashing:
            raise ValueError(f"record keys {clashing} are reserved: the writer logs them itself")
        entry = {"step": int(step), "time": float(t)}
        for key, value in record.items():
            if not isinstance(key, str):
                raise ValueError(f"record keys must be strings, got {key!r}")
            entry[key] = json_value(value, key)
        return json.dumps(entry, allow_nan=False)

    def append(self, line: str) -> None:
        """Write one formatted line (rank 0; a no-op elsewhere)."""
        if self._stream is not None:
            self._stream.write(line + "\n")
            self._stream.flush()

    def close(self) -> None:
        """Close the file; further appends are dropped."""
        if self._stream is not None:
            self._stream.close()
            self._stream = None


def json_value(value, key: str):
    """Return ``value`` as plain JSON data, non-finite numbers as None; TypeError names ``key``."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(name): json_value(item, key) for name, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_value(item, key) for item in value]
    raise TypeError(f"record[{key!r}] = {value!r} is not JSON data")


def json_ready(value):
    """Return ``value`` with NumPy values as Python ones and non-finite floats as None.

    Lenient where :func:`json_value` is strict: other objects pass through unchanged, so that a
    summary written after a failure is written whatever it holds.
    """
    if isinstance(value, Mapping):
        return {str(key): json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
