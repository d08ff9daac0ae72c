"""``python -m dolfinx_invertible.io.paraview inspect|render|animate ...``.

The same as ``dolfinx-invertible paraview ...`` (:mod:`dolfinx_invertible.scenes.pictures`).
"""

import sys

from dolfinx_invertible.cli import main

sys.exit(main(["paraview", *sys.argv[1:]]))
