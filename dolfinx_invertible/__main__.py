"""``python -m dolfinx_invertible``: the command line (see :mod:`dolfinx_invertible.cli`)."""

import sys

from dolfinx_invertible.cli import main

if __name__ == "__main__":
    sys.exit(main())
