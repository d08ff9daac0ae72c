"""Pytest configuration shared by every test folder.

Under MPI (more than one rank) only the tests marked ``mpi`` are collected: the others check
nothing that a parallel run would add, and deselecting them keeps the parallel report short.
"""

import os

import pytest


def pytest_configure(config):
    """Ready the platform before any test module imports DOLFINx, except in xdist's controller.

    ``_compat`` loads the MPI library the PyPI DOLFINx wheel needs first. The constitutive tests
    run without DOLFINx. xdist's controller runs no tests and must not start MPI: its workers
    would inherit the MPI singleton's environment, and an ``mpirun`` a test starts from there
    exits at once.
    """
    controller = bool(getattr(config.option, "numprocesses", None))
    if controller and "PYTEST_XDIST_WORKER" not in os.environ:
        return
    try:
        import dolfinx_invertible._compat  # noqa: F401
    except ImportError:
        pass


def _comm_size() -> int:
    try:
        from mpi4py import MPI
    except ImportError:
        return 1
    return MPI.COMM_WORLD.size


def pytest_collection_modifyitems(config, items):
    """Deselect the tests not marked ``mpi`` when running on more than one rank."""
    if _comm_size() <= 1:
        return
    selected = [item for item in items if item.get_closest_marker("mpi") is not None]
    deselected = [item for item in items if item.get_closest_marker("mpi") is None]
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = selected


@pytest.fixture
def directory(tmp_path_factory):
    """One directory shared by all ranks (rank 0's temporary directory)."""
    from mpi4py import MPI

    comm = MPI.COMM_WORLD
    path = tmp_path_factory.mktemp("output") if comm.rank == 0 else None
    return comm.bcast(path, root=0)
