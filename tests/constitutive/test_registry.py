"""Each model and extension declares its id and the registries check them; every registered model
and extension is dispatched to its own module, and the batch API needs no DOLFINx."""

import os
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from constitutive_helpers import LAM, MU, compiled_caller

import dolfinx_invertible as di
from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.constitutive.extensions import EXTENSIONS, c1, c2, ife
from dolfinx_invertible.constitutive.extensions import registry as extension_registry
from dolfinx_invertible.constitutive.models import MODELS
from dolfinx_invertible.constitutive.models import registry as model_registry
from dolfinx_invertible.constitutive.principal import principal_derivatives
from dolfinx_invertible.constitutive.registry_ids import ordered_by_id


def test_ids_are_positions():
    assert [model.model_id for model in MODELS] == list(range(len(MODELS)))
    assert EXTENSIONS[0] is None
    assert [extension.extension_id for extension in EXTENSIONS[1:]] == list(
        range(1, len(EXTENSIONS))
    )
    assert len({model.__module__ for model in MODELS}) == len(MODELS)


def test_each_class_declares_its_id():
    """Compiled kernels and numba's disk cache key on these numbers: they never change."""
    declared = {model.__name__: vars(model)["model_id"] for model in MODELS}
    assert declared == {"NeoHookean": 0, "Corotated": 1, "FixedCorotated": 2,
                        "StableNeoHookean": 3, "ARAP": 4, "StVK": 5}  # fmt: skip
    declared = {extension.__name__: vars(extension)["extension_id"] for extension in EXTENSIONS[1:]}
    assert declared == {"C1": 1, "C2": 2, "IFE": 3}
    assert extension_registry.NONE_ID == 0


def _classes(**ids):
    """Classes named after the keywords, each declaring ``model_id`` (None: declaring none)."""
    return tuple(
        type(name, (di.Model,), {} if value is None else {"model_id": value})
        for name, value in ids.items()
    )


def test_registry_orders_by_the_declared_ids():
    ordered = ordered_by_id(_classes(B=1, C=2, A=0), "model_id", first=0)
    assert [cls.__name__ for cls in ordered] == ["A", "B", "C"]


@pytest.mark.parametrize(
    "ids, message",
    [
        ({"A": 0, "B": 0}, "A and B both declare model_id = 0"),
        ({"A": 0, "B": 2}, "model_ids must be 0..1 without a gap; declared: A = 0, B = 2"),
        ({"A": 1, "B": 2}, "model_ids must be 0..1 without a gap"),
        ({"A": 0, "B": None}, "B must declare an integer model_id"),
        ({"A": 0, "B": True}, "B must declare an integer model_id"),
    ],
)
def test_registry_rejects_repeated_missing_or_gapped_ids(ids, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        ordered_by_id(_classes(**ids), "model_id", first=0)


def test_an_inherited_id_is_no_declaration():
    subclass = type("Stiffer", (di.NeoHookean,), {})
    with pytest.raises(ValueError, match="Stiffer must declare an integer model_id"):
        ordered_by_id((di.NeoHookean, subclass), "model_id", first=0)


def _compiled_tables(model_id):
    """The compiled dispatch, with the id a compile-time literal as in the kernels."""
    import numba

    def tables(sigma, f, h):
        model_registry._tables(model_id, sigma, MU, LAM, f, h)
        return model_registry._constants(model_id, MU, LAM)

    return numba.njit(tables)


@pytest.mark.parametrize("model", MODELS, ids=lambda model: model.__name__)
def test_every_model_is_dispatched_to_its_module(model, rng):
    module = sys.modules[model.__module__]
    sigma = rng.uniform(0.5, 1.5, 3)
    f_own, h_own, f_registry, h_registry = (np.zeros((3, 5)) for _ in range(4))
    compiled_caller(module.tables)(sigma, MU, LAM, f_own, h_own)
    compiled_caller(model_registry._tables)(model.model_id, sigma, MU, LAM, f_registry, h_registry)
    assert np.array_equal(f_own, f_registry) and np.array_equal(h_own, h_registry)
    f_compiled, h_compiled = np.zeros((3, 5)), np.zeros((3, 5))
    constants = _compiled_tables(model.model_id)(sigma, f_compiled, h_compiled)
    assert np.array_equal(f_own, f_compiled) and np.array_equal(h_own, h_compiled)
    assert constants == compiled_caller(module.constants)(MU, LAM)
    assert compiled_caller(module.constants)(MU, LAM) == compiled_caller(model_registry._constants)(
        model.model_id, MU, LAM
    )
    assert compiled_caller(module.slopes)(sigma[0], sigma[1], MU, LAM) == compiled_caller(
        model_registry._slopes
    )(model.model_id, sigma[0], sigma[1], MU, LAM)
    # Models written in invariants, and only those, take the SVD-free path.
    available, *terms = compiled_caller(model_registry.model_invariant_terms)(
        model.model_id, 3.1, 3.3, 1.05, 3, np.array([MU, LAM])
    )
    assert available == hasattr(module, "invariant_terms")
    if available:
        assert tuple(terms) == compiled_caller(module.invariant_terms)(3.1, 3.3, 1.05, 3, MU, LAM)


EXTENSION_FUNCTIONS = {
    "C1": c1.c1_derivatives,
    "C2": c2.c2_derivatives,
    "IFE": ife.ife_derivatives,
}


@pytest.mark.parametrize("extension", EXTENSIONS[1:], ids=lambda extension: extension.__name__)
def test_every_extension_is_dispatched_to_its_module(extension):
    own = EXTENSION_FUNCTIONS[extension.__name__]
    sigma = np.array([0.3, 0.8, 0.95])  # inside every extension's region
    model = di.NeoHookean(mu=MU, lam=LAM)
    material = di.Material(model, extension())
    results = []
    for function in (
        lambda work: compiled_caller(principal_derivatives)(
            model.model_id, extension.extension_id, False, sigma, 3, material.parameters, 2, work
        ),
        lambda work: compiled_caller(own)(model.model_id, sigma, 3, material.parameters, 2, work),
    ):
        work = np.zeros(ws.WORKSPACE_SIZE)
        energy, region = function(work)
        results.append((energy, region, work[ws.G : ws.G + 3].copy(), work[ws.H : ws.H + 9].copy()))
    (e1, r1, g1, h1), (e2, r2, g2, h2) = results
    assert r1 == r2 > 0
    assert e1 == e2 and np.array_equal(g1, g2) and np.array_equal(h1, h2)


def test_a_material_compiles_only_its_own_chain(tmp_path):
    """Neo-Hookean + C2 in 3D compiles Neo-Hookean and C2 in 3D: no other model's or
    extension's functions and no 2D twin (the ids and the dimension are compile-time literals,
    the dispatch an overload resolved while typing)."""
    script = textwrap.dedent(
        """
        import numpy as np
        import dolfinx_invertible as di
        from dolfinx_invertible.constitutive import invariants, svd, tangent
        from dolfinx_invertible.constitutive.extensions import c1, c2, ife
        from dolfinx_invertible.constitutive.models import corotated, neo_hookean, separable, stvk
        m = di.Material(di.NeoHookean(mu=1.0, lam=2.0), extension=di.C2())
        F = np.array([np.diag([1.0, 1.0, -0.5]), np.eye(3)])
        m.energy(F), m.stress(F), m.tangent(F), m.tangent(F, project=False)
        used = {"neo_hookean": neo_hookean.tables, "c2": c2._C2_DERIVATIVES[3],
                "svd": svd._POLAR_SVD[3], "clamp": tangent._CLAMP_SYMMETRIC[3],
                "invariant tangent": invariants._INVARIANT_TANGENT[3]}
        unused = {"corotated": corotated.tables, "stvk": stvk.tables,
                  "c1": c1.c1_derivatives, "ife": ife.ife_derivatives}
        twins = (c2._C2_DERIVATIVES, separable._SEPARABLE_DERIVATIVES,
                 separable._SEPARABLE_ANCHOR, invariants._INVARIANT_TANGENT,
                 invariants._SPECTRAL_PROJECTION, tangent._STRESS_DERIVATIVE,
                 tangent._CLAMP_SYMMETRIC, tangent._WORKSPACE_FIRST_PIOLA, svd._POLAR_SVD)
        unused.update({twin[2].py_func.__qualname__: twin[2] for twin in twins})
        assert all(f.signatures for f in used.values()), used
        compiled = [name for name, f in unused.items() if f.signatures]
        assert not compiled, compiled
        """
    )
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    completed = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=600, env=environment
    )
    assert completed.returncode == 0, completed.stderr[-2000:]


def test_batch_api_never_loads_dolfinx():
    script = textwrap.dedent(
        """
        import sys
        import numpy as np
        import dolfinx_invertible as di
        m = di.Material(di.NeoHookean(mu=1.0, lam=2.0), extension=di.C2())
        F = np.diag([1.0, 1.0, -0.5])
        m.energy(F), m.stress(F), m.tangent(F)
        loaded = [name for name in ("dolfinx", "petsc4py", "ufl", "basix") if name in sys.modules]
        assert not loaded, loaded
        """
    )
    completed = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=600
    )
    assert completed.returncode == 0, completed.stderr[-2000:]
