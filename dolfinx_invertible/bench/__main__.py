"""``python -m dolfinx_invertible.bench NAME``: ``python -m dolfinx_invertible bench NAME``."""

import sys

from dolfinx_invertible.cli import main

sys.exit(main(["bench", *sys.argv[1:]]))
