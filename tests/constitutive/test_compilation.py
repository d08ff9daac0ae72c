"""How the package compiles: compiled-only functions keep IR, the SVD path may compile in a helper.

Each check that needs an empty numba cache runs in a child process on its own ``NUMBA_CACHE_DIR``
(numba reads it at import).
"""

import gc
import logging
import os
import re
import shutil
import subprocess
import sys
import textwrap

from mpi4py import MPI

import dolfinx
import dolfinx.fem.petsc
import numba
import numpy as np
import pytest

import dolfinx_invertible as di
from dolfinx_invertible import _compat
from dolfinx_invertible.constitutive import compiled, svd_path
from dolfinx_invertible.constitutive import workspace as ws
from dolfinx_invertible.fem.kernels.constants import SVD_PATH_SLOT

_MODULE = """
import numba
from dolfinx_invertible.constitutive.compiled import compiled_only


@compiled_only
def inner(x):
    return 3.0 * x + 1.0


@numba.njit(cache=True)
def first_caller(x):
    return inner(x) * 2.0


@numba.njit(cache=True)
def second_caller(x):
    return inner(x) - 1.0
"""


def _run(script: str, cache, cwd=None) -> str:
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    if cwd is not None:  # the scripts import modules written there, also under PYTHONSAFEPATH
        environment["PYTHONPATH"] = os.pathsep.join(
            [str(cwd), *filter(None, [os.environ.get("PYTHONPATH")])]
        )
    completed = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(script)],
        capture_output=True,
        text=True,
        timeout=900,
        env=environment,
        cwd=cwd,
    )
    assert completed.returncode == 0, completed.stderr[-3000:]
    return completed.stdout


def test_compiled_only_function_has_ir_but_no_machine_code(tmp_path):
    (tmp_path / "chain.py").write_text(_MODULE)
    script = """
        import numba
        import pytest
        import chain

        assert chain.first_caller(2.0) == 14.0
        (signature, result), = chain.inner.overloads.items()
        library = result.library
        assert type(library).__name__ == "LinkOnlyCodeLibrary"
        # No machine code of its own: the caller linked its IR in.
        assert library.get_pointer_to_function(result.fndesc.llvm_func_name) == 0
        assert result.fndesc.llvm_func_name in library.get_llvm_str()
        with pytest.raises(TypeError, match="compiled code"):
            chain.inner(2.0)
        print(sum(chain.inner.stats.cache_misses.values()))
    """
    assert _run(script, tmp_path / "cache", cwd=tmp_path).split()[-1] == "1"
    # A new caller in a new process loads the callee's IR from the disk cache and links it.
    script = """
        import chain

        assert chain.second_caller(2.0) == 6.0
        assert chain.first_caller(2.0) == 14.0
        hits = chain.inner.stats.cache_hits, chain.first_caller.stats.cache_hits
        print(*(sum(counts.values()) for counts in hits))
    """
    assert _run(script, tmp_path / "cache", cwd=tmp_path).split()[-2:] == ["1", "1"]


def _doubled(x):
    return 2.0 * x


@compiled.compiled_only
def _doubled_inside(x):
    return 2.0 * x + 0.5  # not the Python body's value: tells which one ran


@compiled.compiled_overload(_doubled)
def _doubled_compiled(x):
    def implementation(x):
        return _doubled_inside(x)

    return implementation


@numba.njit
def _doubled_caller(x):
    return _doubled(x) + 1.0


def test_compiled_overload_keeps_unoptimised_ir_and_no_machine_code():
    assert _doubled_caller(1.0) == 3.5
    ((_, result),) = _doubled_caller.overloads.items()
    linked = [
        library for library in result.library._linking_libraries if "implementation" in library.name
    ]
    assert len(linked) == 1
    library = linked[0]
    assert type(library).__name__ == "LinkOnlyCodeLibrary"
    ir = library.get_llvm_str()
    defined = re.search(r'^define [^@]*@"?([^"(\s]*implementation[^"(\s]*)"?\(', ir, re.MULTILINE)
    assert defined is not None
    assert library.get_pointer_to_function(defined.group(1)) == 0
    # Its module is linked, not optimised: the one-line callee is still called, not inlined.
    assert re.search(r"call .*_doubled_inside", ir)


@pytest.mark.parametrize("d", [2, 3])
def test_calls_from_python_find_their_compiled_loop_without_typing(monkeypatch, d):
    """The batch API's loops, once compiled, are called without numba typing anything again.

    A Python int that a loop needs as a literal (an id, the dimension) would be typed as a
    plain integer on every call before its literal version is found: a tenth of a second per
    call, every step of a scene that records its diagnostics.
    """
    material = di.Material(di.NeoHookean(mu=1.0, lam=1.0), extension=di.C2(eps=0.9))
    F = np.stack([np.eye(d), np.diag([1.0] * (d - 1) + [-0.5])])
    sigma = np.array([[1.0] * d, [1.0] * (d - 1) + [-0.5]])
    calls = {
        "polar_svd": lambda: di.polar_svd(F),
        "energy": lambda: material.energy(F),
        "stress": lambda: material.stress(F),
        "tangent": lambda: material.tangent(F),
        "regions": lambda: material.regions(F),
        "stress_sigma": lambda: material.stress_sigma(sigma),
    }
    for call in calls.values():
        call()
    typed = []
    compile_for_args = numba.core.dispatcher.Dispatcher._compile_for_args

    def counting(dispatcher, *arguments, **options):
        typed.append(dispatcher.py_func.__qualname__)
        return compile_for_args(dispatcher, *arguments, **options)

    monkeypatch.setattr(numba.core.dispatcher.Dispatcher, "_compile_for_args", counting)
    for name, call in calls.items():
        call()
        assert typed == [], f"{name} typed {typed} again"


def test_processes_name_their_compiled_functions_apart(tmp_path):
    """The same closure compiled first thing in two processes gets two machine-code names.

    numba names compiled code by qualified name, argument types and a per-process counter, and
    the JIT binds a cached object's calls by name: with equal counters, two specialisations of
    one closure compiled in two processes (the 2D and 3D SVD paths, say) could share a name, and
    a process loading both would run one's code for the other.
    """
    script = """
        import numba
        import dolfinx_invertible.constitutive.compiled

        def specialise(scale):
            return numba.njit(lambda x: scale * x)

        function = specialise(2.0)
        assert function(1.0) == 2.0
        (result,) = function.overloads.values()
        print(result.fndesc.mangled_name)
    """
    names = {_run(script, tmp_path / f"cache{index}").split()[-1] for index in range(2)}
    assert len(names) == 2


_RACING = """
import sys

from dolfinx_invertible.constitutive.compiled import python_callable


def specialise(k):
    def scaled(x):
        return x * k + k

    return python_callable(scaled)


first, step = int(sys.argv[1]), int(sys.argv[2])
for k in range(first, 80, step):
    assert specialise(float(k))(2.0) == 3.0 * k, k
"""


def test_concurrent_saves_of_one_function_keep_its_cache_consistent(tmp_path):
    """Two processes cache different specialisations of one function at once; a third loads all.

    The specialisations share one index file. Saved without the lock, the index could name a
    data file holding another specialisation (numba's plain cache returned k = 49's code for
    k = 48 here, in one run of two).
    """
    (tmp_path / "racing.py").write_text(_RACING)
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    for _ in range(2):
        shutil.rmtree(tmp_path / "cache", ignore_errors=True)
        writers = [
            subprocess.Popen(
                [sys.executable, "racing.py", str(first), "2"], cwd=tmp_path, env=environment
            )
            for first in (0, 1)
        ]
        assert [writer.wait(timeout=600) for writer in writers] == [0, 0]
        reader = subprocess.run(
            [sys.executable, "racing.py", "0", "1"],
            cwd=tmp_path,
            env=environment,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert reader.returncode == 0, reader.stderr[-2000:]


def test_compiled_in_a_helper_is_loaded_from_the_cache(tmp_path):
    material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
    key = (material.model.model_id, material.extension_id, 2)
    script = f"""
        import numpy as np
        import dolfinx_invertible as di
        from dolfinx_invertible.constitutive import compiled, svd_path

        key = {key}
        svd_path.compile_svd_path_ahead(*key)
        helper = compiled._AHEAD[svd_path._helper_key(*key)]
        assert helper is not None and helper.poll() is None  # still compiling
        svd_path.svd_path_address(*key)
        assert helper.returncode == 0
        # This process loaded what the helper wrote instead of compiling it.
        assert svd_path._COMPILED[key].cache_hits == 1
        # A cell kernel likewise.
        from dolfinx_invertible.fem.kernels import compilation

        kernel = ("tangent", *key[2:], *key[:2])
        compilation.compile_kernel_ahead(*kernel)
        assert compiled.compiling_ahead(("kernel", *kernel))
        compilation.kernel_address(*kernel)
        assert not compiled._AHEAD and compilation._COMPILED[kernel].cache_hits == 1
        material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
        F = np.array([[0.8, 0.3], [0.1, -0.4]])
        print(repr(material.stress(F).ravel().tolist()))
    """
    cache = tmp_path / "cache"
    stress = _run(script, cache).strip().splitlines()[-1]
    # On a cache that holds it, nothing starts: the path is loaded on the spot.
    script = f"""
        from dolfinx_invertible.constitutive import compiled, svd_path

        svd_path.compile_svd_path_ahead(*{key})
        assert not compiled._AHEAD
        assert svd_path._COMPILED[{key}].cache_hits == 1
    """
    _run(script, cache)
    expected = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2()).stress(
        np.array([[0.8, 0.3], [0.1, -0.4]])
    )
    np.testing.assert_allclose(eval(stress), expected.ravel(), rtol=1e-13, atol=1e-13)


def _pretend_a_helper_compiles(monkeypatch, key) -> None:
    """Make the SVD path of ``key`` look unready, with a (trivial) helper still compiling it."""
    monkeypatch.delitem(svd_path._COMPILED, key, raising=False)
    helper = svd_path._helper_key(*key)
    monkeypatch.setitem(compiled._AHEAD, helper, compiled.start_helper("pass"))
    monkeypatch.delitem(svd_path._STAND_INS, key, raising=False)
    exited = compiled.helper_exited
    monkeypatch.setattr(compiled, "helper_exited", lambda asked: asked != helper and exited(asked))


def _call(address: int, F: np.ndarray, params: np.ndarray, order: int):
    d = F.shape[0]
    work = np.zeros(ws.WORKSPACE_SIZE)
    P = np.zeros((d, d))
    C = np.zeros((d * d, d * d))

    def pointer(array):
        return array.ctypes.data_as(svd_path._DOUBLES)

    psi = svd_path._C_TYPE(address)(
        pointer(F), 0, pointer(params), 1, order, pointer(work), pointer(P), pointer(C)
    )
    return psi, P, C


def test_stand_in_binds_the_svd_path_on_its_first_call(monkeypatch):
    material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
    key = (material.model.model_id, material.extension_id, 3)
    F = np.array([[0.9, 0.1, 0.0], [0.0, 1.1, 0.2], [0.0, 0.0, -0.5]])
    real = _call(svd_path.svd_path_address(*key), F, material.parameters, 2)
    _pretend_a_helper_compiles(monkeypatch, key)
    bound = []
    svd_path.bind_svd_path(*key, bound.append)
    assert len(bound) == 1 and key not in svd_path._COMPILED  # nothing waited
    through_stand_in = _call(bound[0], F, material.parameters, 2)
    assert bound[1:] == [svd_path.svd_path_address(*key)] and bound[0] != bound[1]
    for value, expected in zip(through_stand_in, real):
        np.testing.assert_array_equal(value, expected)
    assert np.all(real[2] != 0.0)
    # Bound once: the same stand-in no longer has anyone waiting, and a caller bound now gets
    # the path itself.
    _call(bound[0], F, material.parameters, 1)
    assert len(bound) == 2
    svd_path.bind_svd_path(*key, bound.append)
    assert bound[2] == bound[1]


def test_stand_in_that_cannot_compile_gives_nan(monkeypatch, caplog):
    material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
    key = (material.model.model_id, material.extension_id, 2)
    _pretend_a_helper_compiles(monkeypatch, key)
    bound = []
    svd_path.bind_svd_path(*key, bound.append)

    def broken(*_):
        raise RuntimeError("no compiler today")

    monkeypatch.setattr(svd_path, "svd_path_address", broken)
    with caplog.at_level(logging.ERROR):
        psi, P, C = _call(bound[0], np.diag([1.0, -0.5]), material.parameters, 1)
    assert np.isnan(psi) and np.all(np.isnan(P)) and np.all(C == 0.0)
    assert "no compiler today" in caplog.text and len(bound) == 1


def test_forms_assemble_before_the_helper_is_done(monkeypatch):
    """The kernels call the SVD path through the stand-in, then through the path itself."""
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 3, 2)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    u.interpolate(lambda x: np.stack([-1.6 * x[0] * x[1], 0.1 * x[0]]))  # inverts some cells
    material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
    key = (material.model.model_id, material.extension_id, 2)
    reference_forms = di.HyperelasticForms(u, material)
    expected = dolfinx.fem.petsc.assemble_vector(reference_forms.residual).array.copy()
    _pretend_a_helper_compiles(monkeypatch, key)
    forms = di.HyperelasticForms(u, material)
    residual = forms.residual
    stand_in = forms.constants.value[SVD_PATH_SLOT]
    first = dolfinx.fem.petsc.assemble_vector(residual).array.copy()
    assert forms.path_counts()["residual"][1] > 0  # points took the SVD path
    assert forms.constants.value[SVD_PATH_SLOT] != stand_in  # rebound
    slot = forms.constants.value[SVD_PATH_SLOT : SVD_PATH_SLOT + 1]
    assert slot.view(np.int64)[0] == svd_path.svd_path_address(*key)
    second = dolfinx.fem.petsc.assemble_vector(residual).array.copy()
    np.testing.assert_array_equal(first, expected)
    np.testing.assert_array_equal(second, expected)


def test_forms_dropped_before_the_stand_in_binds_are_written_safely(monkeypatch):
    """The stand-in's first call writes the path's address into constants of forms that may be
    gone: DOLFINx's value array does not keep its Constant alive, so the binding must, until then.
    """
    mesh = dolfinx.mesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    u.interpolate(lambda x: np.stack([-1.6 * x[0] * x[1], 0.1 * x[0]]))  # inverts some cells
    material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
    key = (material.model.model_id, material.extension_id, 2)
    _pretend_a_helper_compiles(monkeypatch, key)
    dropped = di.HyperelasticForms(u, material)
    assert dropped.residual is not None  # built: bound to the stand-in
    owner = _compat.cpp_object(dropped.constants)
    del dropped
    gc.collect()
    # Our reference, getrefcount's argument and the waiting binding's (C++ objects of newer
    # DOLFINx take no weak references, so the count tells).
    held = sys.getrefcount(owner)
    later = di.HyperelasticForms(u, material)
    dolfinx.fem.petsc.assemble_vector(later.residual)  # the stand-in's first call binds both
    address = svd_path.svd_path_address(*key)
    assert owner.value[SVD_PATH_SLOT : SVD_PATH_SLOT + 1].view(np.int64)[0] == address
    gc.collect()
    assert sys.getrefcount(owner) == held - 1  # the binding held it until bound


def test_binding_after_the_helper_exited_needs_no_stand_in(monkeypatch):
    material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
    key = (material.model.model_id, material.extension_id, 3)
    _pretend_a_helper_compiles(monkeypatch, key)
    waiting = []
    svd_path.bind_svd_path(*key, waiting.append)
    monkeypatch.setattr(compiled, "helper_exited", lambda asked: True)
    later = []
    svd_path.bind_svd_path(*key, later.append)
    address = svd_path.svd_path_address(*key)
    assert later == [address]
    assert waiting[1:] == [address] and waiting[0] != address  # the stand-in, then the path
    assert not svd_path._STAND_INS[key][1]


def test_failed_helper_leaves_the_compilation_to_the_caller(monkeypatch, caplog):
    material = di.Material(di.NeoHookean(mu=1.0, lam=2.0), di.C2())
    key = (material.model.model_id, material.extension_id, 3)
    monkeypatch.delitem(svd_path._COMPILED, key, raising=False)
    helper = compiled.start_helper("raise SystemExit(3)")
    monkeypatch.setitem(compiled._AHEAD, svd_path._helper_key(*key), helper)
    with caplog.at_level(logging.WARNING):
        address = svd_path.svd_path_address(*key)
    assert address != 0 and not compiled.compiling_ahead(svd_path._helper_key(*key))
    assert "exit 3" in caplog.text
    F = np.array([[0.9, 0.1, 0.0], [0.0, 1.1, 0.2], [0.0, 0.0, -0.5]])
    assert np.all(np.isfinite(material.stress(F)))


def test_helpers_can_be_switched_off(monkeypatch):
    monkeypatch.setenv(compiled.HELPER_VARIABLE, "0")
    assert not compiled.helpers_allowed()
    monkeypatch.setenv(compiled.HELPER_VARIABLE, "1")
    assert compiled.helpers_allowed() == (len(os.sched_getaffinity(0)) > 1)


def _two_materials():
    return [
        di.Material(di.NeoHookean(mu=1.0, lam=2.0), None),
        di.Material(di.Corotated(mu=1.0, lam=2.0), None),
    ]


@pytest.mark.parametrize("helper_fails", [False, True])
def test_precompile_deals_the_chains_to_a_helper_on_each_further_core(monkeypatch, helper_fails):
    from dolfinx_invertible.fem.kernels import KERNEL_KINDS, compilation

    materials = _two_materials()
    chains = [(m.model.model_id, m.extension_id, 2) for m in materials]
    statements = []
    start = compiled.start_helper

    def record(statement):
        statements.append(statement)
        return start("raise SystemExit(3)" if helper_fails else statement)

    monkeypatch.setenv(compiled.HELPER_VARIABLE, "1")
    monkeypatch.setattr(compiled, "available_cores", lambda: 2)
    monkeypatch.setattr(compiled, "start_helper", record)
    for chain in chains:
        for kind in KERNEL_KINDS:
            monkeypatch.delitem(compilation._COMPILED, (kind, 2, *chain[:2]), raising=False)
    seconds = compilation.precompile(dimensions=(2,), materials=materials)
    # This process takes the first chain, the one helper the second.
    assert len(statements) == 1 and repr([chains[1]]) in statements[0]
    assert repr(chains[0]) not in statements[0]
    pieces = ("svd path", *KERNEL_KINDS)
    assert list(seconds) == [(piece, 2, repr(m)) for m in materials for piece in pieces]
    assert all(np.isfinite(value) and value >= 0.0 for value in seconds.values())
    # Whether the helper compiled them or failed, every kernel is in this process afterwards.
    for chain in chains:
        for kind in KERNEL_KINDS:
            assert (kind, 2, *chain[:2]) in compilation._COMPILED


def test_precompile_on_one_core_starts_no_helper(monkeypatch):
    from dolfinx_invertible.fem.kernels import compilation

    monkeypatch.setattr(compiled, "available_cores", lambda: 1)
    monkeypatch.setattr(compiled, "start_helper", lambda statement: pytest.fail(statement))
    seconds = compilation.precompile(dimensions=(2,), materials=_two_materials())
    assert len(seconds) == 2 * 4
