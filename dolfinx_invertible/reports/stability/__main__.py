"""Entry point of a worker of the study's pool (:mod:`.pool`): ``--worker`` serves cells."""

import sys

from dolfinx_invertible.reports.stability.pool import run_worker

if __name__ == "__main__":
    if sys.argv[1:] == ["--worker"]:
        sys.exit(run_worker())
