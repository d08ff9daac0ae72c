"""ParaView's ``pvbatch`` as a separate process, with a private X display when it renders.

:func:`run_script` hands a request (JSON) to the script ``paraview_scripts/series.py``, run by
``pvbatch``, and returns its answer; :func:`find_pvbatch` says which ``pvbatch`` that is.

Why a separate process
----------------------
Debian's ParaView Python modules do import into the venv's Python (same Python, system site
packages), but they load ParaView's own VTK, HDF5 and MPI libraries, which need not match those
of the DOLFINx build at hand, and ParaView's XDMF reader aborts its process on some errors (a
bad HDF5 path). In a child process neither can harm the caller: an abort becomes a
:class:`ParaViewError`. The child gets ``--no-mpi`` and none of the caller's MPI launcher
variables, so that a DOLFINx process running under ``mpirun`` can call these functions (on one
rank).

Displays
--------
Reading needs no display. Rendering does: Debian bookworm's ParaView 5.11 is built for X only
(no EGL, no OSMesa; ``--force-offscreen-rendering`` still aborts without ``DISPLAY``). So each
rendering run starts its own ``Xvfb`` (Debian package ``xvfb``), which picks a free display
number itself (``-displayfd``), and runs it with ``-noreset``: without it the server resets
when ParaView's first X connection closes, and the next one fails now and then ("bad X server
connection"), as it does under a plain ``xvfb-run -a``. With no ``Xvfb`` installed, an existing
``DISPLAY`` is used.
"""

from __future__ import annotations

import json
import os
import re
import select
import shutil
import subprocess
import tempfile
import time as clock
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = ["ParaViewError", "ParaViewNotFoundError", "find_pvbatch", "run_script"]

_SCRIPT = Path(__file__).resolve().parent.parent / "paraview_scripts" / "series.py"
_INSTALL_HINT = (
    "install Debian's paraview, python3-paraview and xvfb packages (`make test` and `make demo` "
    "install them)"
)
_XVFB_START_SECONDS = 60.0
_STACK_FRAME = re.compile(r"\s*\d+\s+0x[0-9a-f]+ ")
# Variables by which an MPI launcher hands a process its place in a job: a child that inherits
# them takes itself for a rank of the caller's job.
_MPI_ENVIRONMENT_PREFIXES = ("OMPI_", "PMIX_", "PMI_", "HYDRA_", "I_MPI_")


class ParaViewError(RuntimeError):
    """ParaView failed: the message holds its traceback or the end of its output."""


class ParaViewNotFoundError(ParaViewError):
    """ParaView's ``pvbatch`` (or, for rendering, an X display or ``Xvfb``) is not installed."""


def find_pvbatch(executable: str | Path | None = None) -> Path:
    """Return the ``pvbatch`` to run: ``executable``, else ``$PVBATCH``, else the one on PATH.

    Whether it can import ParaView's Python modules shows only when it runs (Debian ships them
    in ``python3-paraview``, a mere recommendation of ``paraview``); the functions that run it
    raise :class:`ParaViewNotFoundError` then.

    Raises
    ------
    ParaViewNotFoundError
        If there is none.
    """
    name = executable or os.environ.get("PVBATCH") or "pvbatch"
    found = shutil.which(str(name))
    if found is None:
        raise ParaViewNotFoundError(f"ParaView's {name} was not found: {_INSTALL_HINT}")
    return Path(found)


def _child_environment() -> dict[str, str]:
    environment = {
        name: value
        for name, value in os.environ.items()
        if not name.startswith(_MPI_ENVIRONMENT_PREFIXES)
        # pvbatch embeds the system Python: a venv's PYTHONHOME would break it.
        and name != "PYTHONHOME"
    }
    return environment


@contextmanager
def _x_display(environment: dict[str, str], log: Path) -> Iterator[dict[str, str]]:
    """Yield ``environment`` with ``DISPLAY`` set to a private Xvfb (or the existing one)."""
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        if environment.get("DISPLAY"):
            yield environment
            return
        raise ParaViewNotFoundError(
            f"rendering needs an X display, and neither Xvfb nor DISPLAY is there: {_INSTALL_HINT}"
        )
    read_end, write_end = os.pipe()
    try:
        # A file, not a pipe: a pipe nobody reads would stall the server once full.
        with open(log, "wb") as log_stream:
            server = subprocess.Popen(
                [xvfb, "-displayfd", str(write_end), "-noreset", "-nolisten", "tcp"]
                + ["-screen", "0", "1280x1024x24"],
                pass_fds=(write_end,),
                stdin=subprocess.DEVNULL,
                stdout=log_stream,
                stderr=subprocess.STDOUT,
            )
    except BaseException:
        os.close(read_end)
        raise
    finally:
        os.close(write_end)
    try:
        number = _read_display_number(read_end, _XVFB_START_SECONDS)
        if number is None:
            raise ParaViewError(
                f"Xvfb did not start within {_XVFB_START_SECONDS} s; its output:\n"
                + _tail(log.read_text(errors="replace"))
            )
        yield dict(environment, DISPLAY=f":{number}")
    finally:
        if server.poll() is None:
            server.terminate()
            try:
                server.wait(timeout=30)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def _read_display_number(descriptor: int, timeout: float) -> str | None:
    """Return the number Xvfb writes once it accepts connections; None if it dies or hangs."""
    deadline = clock.monotonic() + timeout
    text = b""
    try:
        while not text.endswith(b"\n"):
            remaining = deadline - clock.monotonic()
            if remaining <= 0 or not select.select([descriptor], [], [], remaining)[0]:
                return None
            chunk = os.read(descriptor, 64)
            if not chunk:  # the server exited
                return None
            text += chunk
    finally:
        os.close(descriptor)
    number = text.strip().decode(errors="replace")
    return number if number.isdigit() else None


def run_script(
    request: dict[str, Any],
    executable: str | Path | None,
    *,
    timeout: float,
    display: bool,
    mpi: bool = False,
) -> dict[str, Any]:
    """Run ``pvbatch`` on ``paraview_scripts/series.py`` with ``request``; return its answer.

    Parameters
    ----------
    request
        The JSON-ready request the script reads (its ``command``: ``inspect`` or ``render``).
    executable
        The ``pvbatch`` to run (see :func:`find_pvbatch`).
    timeout
        Seconds before ParaView is stopped.
    display
        Whether ParaView needs an X display (a private ``Xvfb``, or the existing one).
    mpi
        Let ``pvbatch`` start MPI (one process): ParaView's ADIOS2 reader needs it.

    Returns
    -------
    dict
        The result the script wrote.

    Raises
    ------
    ValueError
        If the script rejected the request with a ``ValueError`` (re-raised here).
    ParaViewNotFoundError
        If ``pvbatch``, ParaView's Python modules, or (with ``display``) both ``Xvfb`` and an X
        display are missing.
    ParaViewError
        If ParaView fails or does not finish within ``timeout``.
    """
    pvbatch = find_pvbatch(executable)
    with tempfile.TemporaryDirectory(prefix="dolfinx_invertible_paraview_") as directory:
        request_path = Path(directory) / "request.json"
        result_path = Path(directory) / "result.json"
        request_path.write_text(json.dumps(request), encoding="utf-8")
        command = [str(pvbatch), *([] if mpi else ["--no-mpi"]), str(_SCRIPT),
                   str(request_path), str(result_path)]  # fmt: skip
        environment = _child_environment()
        try:
            if display:
                with _x_display(environment, Path(directory) / "xvfb.log") as environment:
                    completed = _run(command, environment, timeout)
            else:
                completed = _run(command, environment, timeout)
        except subprocess.TimeoutExpired as error:
            raise ParaViewError(f"{pvbatch} did not finish within {timeout} s") from error
        result = None
        if result_path.is_file():
            result = json.loads(result_path.read_text(encoding="utf-8"))
    if result is None:
        output = (completed.stdout + completed.stderr).strip()
        if "No module named 'paraview'" in output:
            raise ParaViewNotFoundError(
                f"{pvbatch} cannot import ParaView's Python modules: {_INSTALL_HINT}"
            )
        raise ParaViewError(
            f"{pvbatch} exited with code {completed.returncode} without a result; the end of "
            f"its output:\n{_tail(output)}"
        )
    if "error" in result:
        message = result["error"].rstrip()
        last_line = message.splitlines()[-1] if message else ""
        if last_line.startswith("ValueError:"):
            raise ValueError(last_line.removeprefix("ValueError:").strip())
        raise ParaViewError(f"ParaView raised:\n{message}")
    return result


def _run(command: list[str], environment: dict[str, str], timeout: float):
    return subprocess.run(
        command,
        env=environment,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        errors="replace",
        timeout=timeout,
    )


def _tail(text: str, lines: int = 40) -> str:
    # Without the native stack trace ParaView prints when it aborts: the messages before it
    # (HDF5's, VTK's "ERR|" lines) say what went wrong.
    kept = [line for line in text.splitlines() if not _STACK_FRAME.match(line)]
    return "\n".join(kept[-lines:])
