"""numba's private names: each patch is checked at import and falls back to plain numba.

A numba release without a private name a patch needs must still give the same numbers, only
compiled more slowly. The checks that need an empty numba cache or a numba missing a name run in
a child process on their own ``NUMBA_CACHE_DIR``.
"""

import importlib
import os
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

from dolfinx_invertible.constitutive import numba_internals

_VALUES = """
import sys

import numpy as np

import dolfinx_invertible as di


def values():
    rng = np.random.default_rng(3)
    material = di.Material(di.NeoHookean(mu=0.8, lam=1.7), extension=di.C2(eps=0.9))
    out = {}
    for d in (2, 3):
        F = rng.uniform(-1.0, 1.0, (6, d, d)) + np.eye(d)
        F[0] = np.eye(d)
        F[1] = np.diag([1.0] * (d - 1) + [-0.5])  # inverted, inside the extension
        out[f"energy {d}D"] = material.energy(F)
        out[f"stress {d}D"] = material.stress(F)
        out[f"tangent {d}D"] = material.tangent(F)
    # A cell kernel too: the residual of a displacement that inverts some cells.
    from mpi4py import MPI

    import dolfinx
    import dolfinx.fem.petsc

    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 3, 2)
    u = dolfinx.fem.Function(di.vector_function_space(mesh, 1))
    u.interpolate(lambda x: np.stack([-1.6 * x[0] * x[1], 0.1 * x[0]]))
    forms = di.HyperelasticForms(u, material)
    out["residual 2D"] = dolfinx.fem.petsc.assemble_vector(forms.residual).array.copy()
    return out


if __name__ == "__main__":
    np.savez(sys.argv[1], **values())
"""


def _run(arguments, cache, cwd, **variables) -> subprocess.CompletedProcess:
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(cache), **variables}
    environment["PYTHONPATH"] = os.pathsep.join(
        [str(cwd), *filter(None, [os.environ.get("PYTHONPATH")])]
    )
    completed = subprocess.run(
        [sys.executable, *arguments],
        capture_output=True,
        text=True,
        timeout=900,
        env=environment,
        cwd=cwd,
    )
    assert completed.returncode == 0, completed.stderr[-3000:]
    return completed


def test_every_patch_applies_on_this_numba():
    if os.environ.get(numba_internals.PATCHES_VARIABLE, "1").strip() == "0":
        pytest.skip(f"{numba_internals.PATCHES_VARIABLE}=0 turns the patches off")
    assert numba_internals.missing_names() == dict.fromkeys(numba_internals.PATCHES, [])
    assert all(numba_internals.ACTIVE.values())


def test_without_the_patches_the_numbers_are_the_same(tmp_path):
    """Every patch off (as on a numba lacking them all): same energy, stress, tangent, residual."""
    (tmp_path / "material_values.py").write_text(_VALUES)
    script = """
        import sys

        import numpy as np

        from dolfinx_invertible.constitutive import compiled, numba_internals, pointwise, polynomial
        import material_values

        assert not any(numba_internals.ACTIVE.values())
        assert not compiled.helpers_allowed()
        np.savez(sys.argv[1], **material_values.values())
        # Compiled-only functions are plain numba functions now: with machine code, callable.
        assert polynomial._value(0.5, 1.0, 2.0, 0.0, 0.0) == 2.0
        overloads = pointwise.point_energy.overloads.values()
        libraries = [type(result.library).__name__ for result in overloads]
        assert libraries and "LinkOnlyCodeLibrary" not in libraries, libraries
    """
    _run(
        ["-c", textwrap.dedent(script), str(tmp_path / "plain.npz")],
        tmp_path / "cache",
        tmp_path,
        **{numba_internals.PATCHES_VARIABLE: "0"},
    )
    plain = np.load(tmp_path / "plain.npz")
    sys.path.insert(0, str(tmp_path))
    try:
        patched = importlib.import_module("material_values").values()
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("material_values", None)
    assert sorted(plain.files) == sorted(patched)
    for name, expected in patched.items():
        scale = np.max(np.abs(expected))
        np.testing.assert_allclose(
            plain[name], expected, rtol=1e-14, atol=1e-14 * scale, err_msg=name
        )


_CACHED = """
from dolfinx_invertible.constitutive.compiled import python_callable


@python_callable
def scaled(x):
    return 3.0 * x + 1.0
"""


def test_a_missing_private_name_falls_back_with_one_warning(tmp_path):
    """A numba without the cache's ``cache_path``: saves unlocked, everything else patched."""
    (tmp_path / "cached.py").write_text(_CACHED)
    script = """
        import warnings

        from numba.core.caching import FunctionCache

        for cls in FunctionCache.__mro__:
            if "cache_path" in vars(cls):
                delattr(cls, "cache_path")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            from dolfinx_invertible.constitutive import numba_internals
        ours = [warning for warning in caught if "dolfinx_invertible" in str(warning.message)]
        assert len(ours) == 1 and ours[0].category is RuntimeWarning, ours
        assert "locked_cache" in str(ours[0].message) and "cache_path" in str(ours[0].message)
        assert numba_internals.ACTIVE == {
            "function_numbers": True, "locked_cache": False, "compiled_only": True,
            "c_callable": True,
        }

        import cached

        assert cached.scaled(2.0) == 7.0
        print(type(cached.scaled._cache).__name__)
    """
    completed = _run(["-c", textwrap.dedent(script)], tmp_path / "cache", tmp_path)
    assert completed.stdout.split()[-1] == "FunctionCache"  # numba's own, on disk
    assert list((tmp_path / "cache").rglob("*.nbi"))


def _remove(monkeypatch, owner, name: str) -> None:
    """Remove ``owner.name`` wherever ``owner`` (a module or a class) finds it."""
    for holder in getattr(owner, "__mro__", (owner,)):
        if name in vars(holder):
            monkeypatch.delattr(holder, name)


@pytest.mark.parametrize(
    "module, owner, name, patch",
    [
        ("numba.core.bytecode", "FunctionIdentity", "_unique_ids", "function_numbers"),
        ("numba.core.caching", "FunctionCache", "_save_overload", "locked_cache"),
        ("numba.core.codegen", "JITCodeLibrary", "_optimize_final_module", "compiled_only"),
        ("numba.core.codegen", "JITCodeLibrary", "_finalize_final_module", "compiled_only"),
        ("numba.core.compiler", None, "DefaultPassBuilder", "compiled_only"),
        ("numba.core.compiler", "Flags", "no_cpython_wrapper", "compiled_only"),
        ("numba.core.ccallback", None, "CFunc", "c_callable"),
    ],
)
def test_a_missing_private_name_turns_off_its_patch_only(monkeypatch, module, owner, name, patch):
    holder = importlib.import_module(module)
    if owner is not None:
        holder = getattr(holder, owner)
    _remove(monkeypatch, holder, name)
    missing = numba_internals.missing_names()
    assert missing[patch] and any(name in entry for entry in missing[patch])
    assert all(not names for other, names in missing.items() if other != patch)


def test_fallbacks_warn_once_unless_switched_off():
    missing = dict.fromkeys(numba_internals.PATCHES, [])
    missing["compiled_only"] = ["numba.core.codegen.JITCodeLibrary._optimize_final_module"]
    with pytest.warns(RuntimeWarning, match="compiled_only.*_optimize_final_module") as caught:
        active = numba_internals._decide(missing, True)
    assert len(caught) == 1
    assert active == {**dict.fromkeys(numba_internals.PATCHES, True), "compiled_only": False}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not any(numba_internals._decide(missing, False).values())


def test_the_compiled_sources_digest_follows_compiled_modules_only(tmp_path):
    (tmp_path / "kernel.py").write_text("from numba import njit\n")
    (tmp_path / "scene.py").write_text("x = 1\n")
    digest = numba_internals.compiled_sources_digest.__wrapped__
    before = digest(tmp_path)
    (tmp_path / "scene.py").write_text("x = 2\n")
    assert digest(tmp_path) == before
    (tmp_path / "kernel.py").write_text("from numba import njit  # edited\n")
    assert digest(tmp_path) != before


_THRESHOLD_ENERGY = """
import sys

import numpy as np

import dolfinx_invertible as di

assert di.__file__.startswith(sys.argv[1]), di.__file__
material = di.Material(di.NeoHookean(mu=345.0, lam=3103.0), extension=di.C2(eps=0.9))
print(repr(float(material.energy_sigma(np.array([[1.6, 1.3, 0.3]]))[0])))
"""


def test_an_edit_to_a_called_module_reaches_its_cached_callers(tmp_path):
    """C2's root finder lives in polynomial.py; the cached C2 energy must follow an edit to it.

    numba's own stamp is the calling function's file (c2.py, unchanged here): with it alone the
    second run would load the first run's machine code.
    """
    package = tmp_path / "copy"
    source = Path(numba_internals.__file__).resolve().parents[1]
    shutil.copytree(
        source, package / "dolfinx_invertible", ignore=shutil.ignore_patterns("__pycache__")
    )
    (tmp_path / "energy.py").write_text(_THRESHOLD_ENERGY)
    arguments = [str(tmp_path / "energy.py"), str(package)]
    cache = tmp_path / "cache"
    first = float(_run(arguments, cache, package).stdout)
    polynomial = package / "dolfinx_invertible" / "constitutive" / "polynomial.py"
    text = polynomial.read_text()
    marker = "    return _bracketed_root(0.0, 1.0, c0, c1, c2, c3)"
    assert text.count(marker) == 1
    polynomial.write_text(text.replace(marker, "    return 0.5"))
    second = float(_run(arguments, cache, package).stdout)
    assert np.isfinite(first) and np.isfinite(second)
    assert second != first
    # Put back, the original root finder's energy returns (the stamp follows the text).
    polynomial.write_text(text)
    assert float(_run(arguments, cache, package).stdout) == first
