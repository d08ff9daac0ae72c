"""The C2 anchor's contracted derivatives against the full derivative tensors of the model."""

import numpy as np
import pytest
from constitutive_helpers import DIMS, MODEL_NAMES, compiled_caller, make_model

from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.models.registry import (
    model_anchor_derivatives,
    model_derivatives,
)

# Both sides sum the same O(1)-sized terms in a different order: a few ulp of the largest.
RTOL = 1e-13


@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("model", MODEL_NAMES)
def test_anchor_contractions_match_full_tensors(rng, model, d):
    instance = make_model(model)
    params = np.concatenate([instance.parameters, [0.9, 0.0]])
    for _ in range(10):
        q = rng.uniform(0.6, 1.4, d)
        a = rng.uniform(-0.5, 0.5, d)
        g = np.zeros(d)
        H = np.zeros((d, d))
        T = np.zeros((d, d, d))
        Q = np.zeros((d, d, d, d))
        f = np.zeros((d, 5))
        h = np.zeros((d, 5))
        psi = compiled_caller(model_derivatives)(
            instance.model_id, q, d, params, 4, g, H, T, Q, f, h
        )
        # NaN everywhere else: a slot the contraction reads but was not given shows up.
        work = np.full(ws.WORKSPACE_SIZE, np.nan)
        work[ws.Q_POINT : ws.Q_POINT + d] = q
        work[ws.A_OFFSET : ws.A_OFFSET + d] = a
        anchor_psi = compiled_caller(model_anchor_derivatives)(
            instance.model_id, q, d, params, 4, work
        )
        expected = {
            "psi": np.array([psi]),
            "g": g,
            "H": H.ravel(),
            "T[a]": np.einsum("i,ikm->km", a, T).ravel(),
            "T[a, a]": np.einsum("i,j,ijk->k", a, a, T),
            "Q[a, a]": np.einsum("i,j,ijkm->km", a, a, Q).ravel(),
        }
        actual = {
            "psi": np.array([anchor_psi]),
            "g": work[ws.MODEL_G : ws.MODEL_G + d],
            "H": work[ws.MODEL_H : ws.MODEL_H + d * d],
            "T[a]": work[ws.T1 : ws.T1 + d * d],
            "T[a, a]": work[ws.T2 : ws.T2 + d],
            "Q[a, a]": work[ws.Q2 : ws.Q2 + d * d],
        }
        for name, value in expected.items():
            scale = max(np.abs(value).max(), 1.0)
            np.testing.assert_allclose(actual[name], value, rtol=0, atol=RTOL * scale, err_msg=name)
