"""Pytest configuration shared by every test folder.

Under MPI (more than one rank) only the tests marked ``mpi`` are collected: the others check
nothing that a parallel run would add, and deselecting them keeps the parallel report short.

``--chains covering`` (the compat lanes of other DOLFINx and numba versions,
docs/compatibility.md) runs each test parametrised over the models and the extensions on a
covering subset of its pairs: every model and every extension at least once, every other
parameter (the dimension, the cases) in full. Each (model, extension, dimension) is its own
compiled chain, so the full matrix, which the host lane runs, costs a lane most of its time in
compilation without exercising code that the covering subset leaves out.
"""

import collections
import os

import pytest

#: The parameter names under which the tests receive a model and an extension.
_MODEL_PARAMETERS = ("model",)
_EXTENSION_PARAMETERS = ("ext", "extension")


def pytest_addoption(parser):
    """Add ``--chains``: ``all`` model × extension pairs (default) or a ``covering`` subset."""
    parser.addoption(
        "--chains",
        choices=("all", "covering"),
        default="all",
        help="run the tests parametrised over models and extensions on all pairs (default) or "
        "on a covering subset: every model and every extension at least once",
    )


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


def _parameter(item, names):
    """Return (found, value) of the first of ``names`` the item is parametrised over."""
    parameters = getattr(getattr(item, "callspec", None), "params", {})
    for name in names:
        if name in parameters:
            return True, parameters[name]
    return False, None


def _in_covering_subset(items) -> list[bool]:
    """Whether each item is in the covering subset of its test's model × extension pairs.

    With the models and the extensions numbered in the order first collected, model i goes
    with extension i mod (number of extensions), the same pairs in every test; a test without
    that extension takes its own extension i mod (its number of extensions) instead. A test
    over the models alone runs one of its own models, a different one from test to test; one
    marked ``extensions(...)`` (the extensions its body builds materials with, ``None`` for the
    plain model) runs one whose pairs with those extensions the tests above keep anyway, so that
    it adds no compiled chain to the lane.
    """
    models: list = []
    extensions: list = []
    own_models = collections.defaultdict(list)
    own_extensions = collections.defaultdict(list)
    for item in items:
        has_model, model = _parameter(item, _MODEL_PARAMETERS)
        has_extension, extension = _parameter(item, _EXTENSION_PARAMETERS)
        if has_model and model not in models:
            models.append(model)
        if has_model and model not in own_models[_function(item)]:
            own_models[_function(item)].append(model)
        if has_extension:
            if extension not in extensions:
                extensions.append(extension)
            own = own_extensions[_function(item)]
            if extension not in own:
                own.append(extension)
    functions = list(dict.fromkeys(_function(item) for item in items))
    keep = [True] * len(items)
    kept_pairs = set()
    for index, item in enumerate(items):
        has_model, model = _parameter(item, _MODEL_PARAMETERS)
        has_extension, extension = _parameter(item, _EXTENSION_PARAMETERS)
        if has_model and has_extension:
            i = models.index(model)
            own = own_extensions[_function(item)]
            partner = extensions[i % len(extensions)]
            if partner not in own:
                partner = own[i % len(own)]
            keep[index] = extension == partner
            if keep[index]:
                kept_pairs.add((_name(model), _name(extension)))
    for index, item in enumerate(items):
        has_model, model = _parameter(item, _MODEL_PARAMETERS)
        has_extension, _ = _parameter(item, _EXTENSION_PARAMETERS)
        if has_model and not has_extension:
            # One of the test's own models: a test over some of the models keeps one too.
            own = own_models[_function(item)]
            marker = item.get_closest_marker("extensions")
            if marker is not None:
                compiled_anyway = [
                    candidate
                    for candidate in own
                    if all((_name(candidate), _name(used)) in kept_pairs for used in marker.args)
                ]
                own = compiled_anyway or own
            keep[index] = model == own[functions.index(_function(item)) % len(own)]
    return keep


def _name(value):
    """A model's or an extension's name, however a test spells it (``None``: no extension)."""
    if value is None or value == "none":
        return None
    if isinstance(value, str):
        return value
    return value.__name__ if isinstance(value, type) else type(value).__name__


def _function(item) -> str:
    """The test function's node id, without its parameters."""
    return item.nodeid.split("[")[0]


def pytest_collection_modifyitems(config, items):
    """Deselect the tests not marked ``mpi`` under MPI, and the pairs ``--chains`` leaves out."""
    keep = [True] * len(items)
    if config.getoption("chains") == "covering":
        keep = _in_covering_subset(items)
    if _comm_size() > 1:
        keep = [
            k and item.get_closest_marker("mpi") is not None
            for item, k in zip(items, keep, strict=True)
        ]
    selected = [item for item, k in zip(items, keep, strict=True) if k]
    deselected = [item for item, k in zip(items, keep, strict=True) if not k]
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
