#!/usr/bin/env bash
# Print a key of everything a test run depends on in the tree: the package, the tests, the
# compat tools and the project file. Equal keys: the same code was tested.
set -euo pipefail
cd "$(dirname "$0")/../.."
find dolfinx_invertible tests tools demos -name '*.py' -print0 | sort -z |
  xargs -0 sha256sum | cat - pyproject.toml | sha256sum | cut -c1-16
