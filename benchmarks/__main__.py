"""``python -m benchmarks NAME`` or ``python path/to/benchmarks NAME``: the package's
``python -m dolfinx_invertible bench NAME``.
"""

import sys

if not __package__:
    from pathlib import Path

    # Run as a folder: Python put the folder itself first on sys.path, where its modules would
    # pass for top-level ones. Load it as the package ``benchmarks`` by its path instead, and
    # put the repository root last on sys.path: a checkout without an installed package still
    # finds its own dolfinx_invertible, and an installed one comes first (the CI's wheel lane
    # tests the installed package).
    folder = Path(__file__).resolve().parent
    if sys.path and Path(sys.path[0]).resolve() == folder:
        del sys.path[0]
    sys.path.append(str(folder.parent))
    from dolfinx_invertible.cli import load_package

    load_package("benchmarks", folder)

from dolfinx_invertible.cli import main  # noqa: E402

sys.exit(main(["bench", *sys.argv[1:]]))
