"""Importing any part of the package loads mpi4py before DOLFINx.

DOLFINx's PyPI wheel finds its MPI library only after mpi4py has loaded it, so a module that
imports DOLFINx first fails there with "libmpi.so.12: cannot open shared object file". Each
subpackage that uses DOLFINx imports mpi4py in its ``__init__``; this checks it in a fresh
interpreter per entry point (once DOLFINx is loaded the order can no longer be seen).
"""

from __future__ import annotations

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


@pytest.mark.parametrize(
    "package",
    ["dolfinx_invertible", "dolfinx_invertible.constitutive", "dolfinx_invertible.fem",
     "dolfinx_invertible.solvers", "dolfinx_invertible.io", "dolfinx_invertible.scenes",
     "dolfinx_invertible.contact"],
)  # fmt: skip
def test_every_name_in_all_is_there(package):
    import importlib

    module = importlib.import_module(package)
    missing = [name for name in module.__all__ if not hasattr(module, name)]
    assert not missing
