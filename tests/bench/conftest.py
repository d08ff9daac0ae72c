"""The benchmarks under test: the repository's ``benchmarks/`` folder, loaded by its path.

The folder is not installed, and the repository root must not go on ``sys.path`` for it: in the
CI's wheel lane (``tools/compat/run.sh``) pytest runs in the root, which also holds the source
``dolfinx_invertible/``, and that copy would then shadow the installed package the lane tests.
Loading the one package by its path adds nothing else to the import path. The benchmarks' own
child processes run the folder itself (``benchmarks.command_line``), which does the same.
"""

import importlib.util
import sys
from pathlib import Path

FOLDER = Path(__file__).resolve().parents[2] / "benchmarks"

if "benchmarks" not in sys.modules:
    _specification = importlib.util.spec_from_file_location(
        "benchmarks", FOLDER / "__init__.py", submodule_search_locations=[str(FOLDER)]
    )
    _package = importlib.util.module_from_spec(_specification)
    sys.modules["benchmarks"] = _package
    _specification.loader.exec_module(_package)
