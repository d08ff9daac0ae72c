"""Importing any part of the package loads mpi4py before DOLFINx.

DOLFINx's PyPI wheel finds its MPI library only after mpi4py has loaded it, so a module that
imports DOLFINx first fails there with "libmpi.so.12: cannot open shared object file". Each
subpackage that uses DOLFINx imports mpi4py in its ``__init__``; this checks it in a fresh
interpreter per entry point (once DOLFINx is loaded the order can no longer be seen).
"""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

CHECK = """
import importlib, sys
importlib.import_module({module!r})
loaded = list(sys.modules)
assert "dolfinx" in loaded, "the module does not load DOLFINx: pick one that does"
assert "mpi4py.MPI" in loaded and loaded.index("mpi4py.MPI") < loaded.index("dolfinx"), loaded
"""

# One module per subpackage that imports DOLFINx but not mpi4py itself (the case that broke).
MODULES = [
    "dolfinx_invertible.scenes.collapse",
    "dolfinx_invertible.fem.spaces",
    "dolfinx_invertible.solvers.problem",
    "dolfinx_invertible.io.xdmf",
    "dolfinx_invertible.contact.boundary",
    "dolfinx_invertible.meshes.cache",
]


@pytest.mark.parametrize("module", MODULES)
def test_mpi4py_is_loaded_before_dolfinx(module):
    completed = subprocess.run(
        [sys.executable, "-c", CHECK.format(module=module)], capture_output=True, text=True
    )
    assert completed.returncode == 0, completed.stderr[-2000:]


PACKAGES = ["dolfinx_invertible", "dolfinx_invertible.constitutive", "dolfinx_invertible.fem",
            "dolfinx_invertible.solvers", "dolfinx_invertible.io", "dolfinx_invertible.scenes",
            "dolfinx_invertible.contact"]  # fmt: skip


@pytest.mark.parametrize("package", PACKAGES)
def test_every_name_in_all_is_there(package):
    module = importlib.import_module(package)
    missing = [name for name in module.__all__ if not hasattr(module, name)]
    assert not missing


def test_each_public_name_is_declared_once():
    """The top level lists the constitutive package's names and its lazy map, nothing by hand.

    A lazy name comes from the module the map names, which defines it; a name that a subpackage
    exports too is the same object there.
    """
    import dolfinx_invertible as di
    from dolfinx_invertible import constitutive

    assert di.__all__ == [*constitutive.__all__, *di._LAZY]
    assert len(set(di.__all__)) == len(di.__all__)
    for name, module in di._LAZY.items():
        value = getattr(di, name)
        assert getattr(importlib.import_module(module), name) is value, name
        assert value.__module__ == module, f"{name} is defined in {value.__module__}"
    for package in PACKAGES[1:]:
        exported = importlib.import_module(package)
        for name in sorted(set(exported.__all__) & set(di.__all__)):
            assert getattr(exported, name) is getattr(di, name), f"{package}.{name}"


def test_scenes_import_no_private_names():
    """The scenes are examples of the public API: no ``_compat``, no other underscored name."""
    import ast
    from pathlib import Path

    import dolfinx_invertible.scenes

    private = []
    for path in sorted(Path(dolfinx_invertible.scenes.__file__).parent.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("dolfinx_inv"):
                names = [node.module, *(alias.name for alias in node.names)]
                private += [
                    f"{path.name}: {name}"
                    for name in names
                    if any(part.startswith("_") for part in name.split("."))
                ]
    assert not private
