"""Pytest plugin for the compat lanes: each rank writes its outcome counts to a JSON file.

Loaded with ``-p pytest_counts`` when ``COMPAT_COUNTS`` names the output file; under MPI every
rank writes ``<COMPAT_COUNTS>.<rank>``, so the lanes' counts are read from files rather than
from interleaved terminal output.
"""

from __future__ import annotations

import json
import os

OUTCOMES = ("passed", "failed", "error", "skipped", "deselected", "xfailed", "xpassed")


def _rank() -> int:
    # Hydra (MPICH) and OpenMPI both say which rank this process is.
    for name in ("PMI_RANK", "OMPI_COMM_WORLD_RANK"):
        if name in os.environ:
            return int(os.environ[name])
    return 0


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    path = os.environ.get("COMPAT_COUNTS")
    if not path:
        return
    # The same tallies as pytest's own summary line ("3 passed, 1 skipped").
    stats = terminalreporter.stats
    counts = {outcome: len(stats.get(outcome, [])) for outcome in OUTCOMES}
    counts["exitstatus"] = int(exitstatus)
    # Why tests were skipped, so that a lane's skips are visible next to its counts.
    reasons: dict[str, int] = {}
    for report in stats.get("skipped", []):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        reason = reason.removeprefix("Skipped: ")
        reasons[reason] = reasons.get(reason, 0) + 1
    counts["skip_reasons"] = reasons
    with open(f"{path}.{_rank()}", "w") as stream:
        json.dump(counts, stream)
