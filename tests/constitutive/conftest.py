"""Fixtures of the constitutive-core tests."""

import numpy as np
import pytest


@pytest.fixture
def rng(request):
    """A numpy Generator seeded from the test id, so each test is reproducible on its own.

    The id is taken as ``tests/<file>::<test>``, independent of the folder the file sits in.
    """
    identity = "tests/" + request.node.nodeid.rsplit("/", 1)[-1]
    seed = sum(ord(c) * (i + 1) for i, c in enumerate(identity)) % (2**32)
    return np.random.default_rng(seed)


@pytest.fixture
def rotation():
    """random_rotation(rng, d): Haar-random rotation with det +1."""
    from constitutive_helpers import random_rotation

    return random_rotation


@pytest.fixture
def with_sigma():
    """with_sigma(rng, sigma): random F = R1 diag(sigma) R2^T for each row of signed sigma."""
    from constitutive_helpers import matrices_with_sigma

    return matrices_with_sigma
