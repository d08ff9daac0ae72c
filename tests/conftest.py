"""Pytest configuration: serial-only tests and shared fixtures.

The `serial` marker itself is registered in pyproject.toml.
"""

import numpy as np
import pytest

# Before any test module imports dolfinx: _compat readies the platform (on the PyPI DOLFINx wheel,
# its MPI library must be loaded first). Hence also no import of helpers (and dolfinx) up here.
import dolfinx_invertible._compat  # noqa: F401


def _comm_size():
    from mpi4py import MPI

    return MPI.COMM_WORLD.size


def pytest_collection_modifyitems(config, items):
    if _comm_size() <= 1:
        return
    skip = pytest.mark.skip(reason="makes no sense in parallel")
    for item in items:
        if item.get_closest_marker("serial") is not None:
            item.add_marker(skip)


@pytest.fixture
def rng(request):
    """A numpy Generator seeded from the test id, so each test is reproducible on its own."""
    seed = sum(ord(c) * (i + 1) for i, c in enumerate(request.node.nodeid)) % (2**32)
    return np.random.default_rng(seed)


@pytest.fixture
def rotation():
    """random_rotation(rng, d): Haar-random rotation with det +1."""
    from helpers import random_rotation

    return random_rotation


@pytest.fixture
def with_sigma():
    """with_sigma(rng, sigma): random F = R1 diag(sigma) R2^T for each row of signed sigma."""
    from helpers import matrices_with_sigma

    return matrices_with_sigma
