"""Every MPI rank computes the same numbers (runs serially and under mpirun).

All ranks import the package at the same moment, so they also race on numba's on-disk cache; a
corrupted or mismatched cache entry would show up here as differing results.
"""

from mpi4py import MPI

import numpy as np
import pytest
from constitutive_helpers import make_material

pytestmark = pytest.mark.mpi

CASES = [("NeoHookean", "C2"), ("FixedCorotated", "C1")]
SEED = 20240611
N = 24


def common_batch(d):
    """Identical on every rank: same seed, about half inverted."""
    rng = np.random.default_rng(SEED + d)
    return np.concatenate(
        [np.eye(d) + 0.3 * rng.standard_normal((N // 2, d, d)), rng.standard_normal((N // 2, d, d))]
    )


def evaluate(m, F):
    return {
        "energy": m.energy(F),
        "stress": m.stress(F),
        "tangent": m.tangent(F, project=True),
        "tangent_unprojected": m.tangent(F, project=False),
    }


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("model,ext", CASES)
def test_same_batch_bitwise_identical(model, ext, d):
    comm = MPI.COMM_WORLD
    F = common_batch(d)
    assert all(np.array_equal(F, G) for G in comm.allgather(F))
    results = evaluate(make_material(model, ext), F)
    for name, r in results.items():
        r = np.ascontiguousarray(r)
        assert np.all(np.isfinite(r)), name
        blobs = comm.allgather(r.tobytes())
        differing = [rank for rank, b in enumerate(blobs) if b != blobs[0]]
        assert not differing, f"{name}: ranks {differing} differ from rank 0"


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("model,ext", CASES)
def test_split_batch_matches_full(model, ext, d):
    comm = MPI.COMM_WORLD
    F = common_batch(d)
    m = make_material(model, ext)
    mine = np.array_split(np.arange(N), comm.size)[comm.rank]
    part = evaluate(m, F[mine])
    full = evaluate(m, F)
    for name in full:
        gathered = np.concatenate(comm.allgather(part[name]))
        # Points are independent; only vectorised vs. scalar loop remainders could change the
        # last bit, hence a few ulp rather than bitwise equality.
        scale = np.max(np.abs(full[name]))
        np.testing.assert_allclose(gathered, full[name], rtol=1e-14, atol=1e-14 * scale)
