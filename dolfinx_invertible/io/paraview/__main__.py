"""``python -m dolfinx_invertible.io.paraview inspect|render ...`` (see :mod:`.cli`)."""

import sys

from dolfinx_invertible.io.paraview.cli import main

sys.exit(main())
