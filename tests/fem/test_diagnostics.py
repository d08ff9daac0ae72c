"""Per-cell diagnostics on real DOLFINx meshes (runs serially and under mpirun)."""

import json

import dolfinx.fem
import numpy as np
import pytest
from dolfinx_helpers import COMM, MATERIALS, affine_displacement, deformation, unit_mesh

from dolfinx_invertible import _compat
from dolfinx_invertible.fem.diagnostics import ENERGY_SENTINEL, cell_diagnostics, summary

pytestmark = pytest.mark.mpi


# --------------------------------------------------------------------------------------------
# cell_diagnostics
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("material_name", list(MATERIALS))
@pytest.mark.parametrize("det", [0.8, -0.5])
@pytest.mark.parametrize("d,degree", [(2, 1), (2, 2), (3, 1)])
def test_affine_deformation(d, degree, det, material_name):
    material = MATERIALS[material_name]()
    A = deformation(d, det)
    mesh = unit_mesh(d)
    diagnostics = cell_diagnostics(affine_displacement(mesh, A, degree), material)

    num_owned = mesh.topology.index_map(d).size_local
    assert set(diagnostics) == {
        "min_J",
        "inverted",
        "energy_density",
        "min_singular_value",
        "region",
    }
    for name, values in diagnostics.items():
        assert values.shape == (num_owned,), name
        assert values.dtype == np.float64, name
        assert np.all(np.isfinite(values)), name

    np.testing.assert_allclose(diagnostics["min_J"], np.linalg.det(A), rtol=0, atol=1e-12)
    assert np.all(diagnostics["inverted"] == (1.0 if det <= 0 else 0.0))
    smallest = np.linalg.svd(A, compute_uv=False)[-1] * np.sign(np.linalg.det(A))
    np.testing.assert_allclose(diagnostics["min_singular_value"], smallest, rtol=1e-12)
    assert np.all(diagnostics["region"] == float(material.regions(A)))

    if material_name == "IFE":
        expected = 0.0  # stress-only: no energy
    else:
        expected = material.energy(A)
        if not np.isfinite(expected):
            expected = ENERGY_SENTINEL
    np.testing.assert_allclose(diagnostics["energy_density"], expected, rtol=1e-12)


def test_region_codes_of_the_cases_above():
    """The affine cases cover the plain model, the extensions and the undefined region."""
    material = MATERIALS["plain"]()
    assert material.regions(deformation(2, 0.8)) == 0
    assert material.regions(deformation(2, -0.5)) == -1
    assert MATERIALS["C2"]().regions(deformation(2, -0.5)) > 0
    assert MATERIALS["C1"]().regions(deformation(3, -0.5)) > 0


def test_summary_counts_all_ranks():
    mesh = unit_mesh(2)
    material = MATERIALS["C2"]()
    # Inverted only left of x = 0.5: u folds the left half over.
    space = _compat.vector_function_space(mesh, 1)
    u = dolfinx.fem.Function(space)
    u.interpolate(lambda x: np.vstack([np.where(x[0] < 0.5, -2.0 * x[0], -1.0), 0.0 * x[1]]))
    diagnostics = cell_diagnostics(u, material)
    result = summary(diagnostics, COMM)

    assert result["cells"] == 32
    # F = diag(-1, 1) on the 16 cells left of x = 0.5, F = I right of it.
    assert result["inverted_cells"] == 16
    assert result["extended_cells"] == 16
    assert result["undefined_cells"] == 0
    assert result["min_J"] == pytest.approx(-1.0, abs=1e-12)
    assert result["min_singular_value"] == pytest.approx(-1.0, abs=1e-12)
    json.dumps(result)  # plain numbers, ready for the log


def test_summary_names_missing_keys():
    with pytest.raises(KeyError, match="region"):
        summary({"min_J": np.ones(2), "inverted": np.zeros(2)}, COMM)
