# Two commands set everything up on a fresh Debian bookworm machine:
#   make demo   -- installs what is missing, then runs the main job (collapse and scatter, MPI)
#   make test   -- installs what is missing, then runs the tests serially and under MPI
SHELL := /bin/bash
VENV := .venv
PYTHON := $(VENV)/bin/python
APT_PACKAGES := python3-dolfinx-real python3-numba python3-gmsh python3-meshio python3-pytest \
	python3-matplotlib python3-tqdm python3-scipy python3-h5py python3-venv python3-pip \
	python3-setuptools python3-pytest-xdist \
	openmpi-bin paraview python3-paraview python3-pil xvfb
# What Debian does not package: IPC Toolkit, for contact between bodies (NumPy and SciPy from
# the Debian packages satisfy its requirements).
PYPI_PACKAGES := ipctk==1.6.1
MPIEXEC := mpirun
PYTEST_MPI := -q -p no:cacheprovider
# The serial suite runs on one pytest worker per core, each test file on one worker (its module
# fixtures, such as a report the file's tests read, are built once). nproc counts
# OMP_NUM_THREADS, which users of MPI codes often set to 1: the cores are counted without it.
TEST_WORKERS ?= $(shell env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)
PYTEST_SERIAL := -q -n $(TEST_WORKERS) --dist loadfile

export OMPI_ALLOW_RUN_AS_ROOT := 1
export OMPI_ALLOW_RUN_AS_ROOT_CONFIRM := 1
# One thread per MPI rank: BLAS threads fighting over two cores only add noise.
export OMP_NUM_THREADS := 1
export OPENBLAS_NUM_THREADS := 1

RUFF_VERSION := 0.17.6

.PHONY: setup system-packages test test-serial test-mpi test-compat demo bench lint clean clean-cache \
	numba-cache-key

# The last step compiles the DOLFINx cell kernels into numba's disk cache (about a minute the
# first time, a second afterwards), so a user's first assembly does not pay for it.
setup: system-packages $(VENV)/.installed numba-cache-key
	$(PYTHON) -m dolfinx_invertible compile

# numba's disk cache is checked against each function's own file only, not against the files of
# the functions it calls (nor against a file's new place after a move): whenever any source file
# of the package changed, drop the whole cache before anything loads from it.
NUMBA_CACHE_KEY := $(VENV)/.numba-source-key
numba-cache-key: | $(VENV)/.installed
	@key=$$(find dolfinx_invertible -name '*.py' -print0 | sort -z | xargs -0 sha256sum | sha256sum); \
	if [ "$$key" != "$$(cat $(NUMBA_CACHE_KEY) 2>/dev/null)" ]; then \
	  $(MAKE) --no-print-directory clean-cache; echo "$$key" > $(NUMBA_CACHE_KEY); \
	fi

# Cheap when nothing is missing: one dpkg-query per package.
system-packages:
	@missing=""; for p in $(APT_PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -n "$$missing" ]; then \
	  echo "installing Debian packages:$$missing"; \
	  sudo=""; [ "$$(id -u)" = 0 ] || sudo=sudo; \
	  $$sudo apt-get update -q && \
	  DEBIAN_FRONTEND=noninteractive $$sudo apt-get install -y -q --no-install-recommends $$missing; \
	fi

$(VENV)/.installed: pyproject.toml | system-packages
	[ -x $(PYTHON) ] || /usr/bin/python3 -m venv --system-site-packages $(VENV)
	$(PYTHON) -m pip install -q --no-deps --no-build-isolation --config-settings editable_mode=compat -e .
	$(PYTHON) -m pip install -q $(PYPI_PACKAGES)
	touch $@

test: lint test-serial test-mpi

# tools/compat/record.sh keeps the counts, so `make test-compat` need not run the host lane again.
test-serial: setup
	tools/compat/record.sh serial $(PYTHON) -m pytest $(PYTEST_SERIAL)

# Under MPI only the tests marked `mpi` are collected (tests/conftest.py).
test-mpi: setup
	tools/compat/record.sh mpi $(MPIEXEC) -n 2 $(PYTHON) -m pytest $(PYTEST_MPI)
	$(MPIEXEC) -n 3 --oversubscribe $(PYTHON) -m pytest $(PYTEST_MPI)

# The suite on every supported DOLFINx: the host's 0.5.2, Debian trixie's 0.9 and the PyPI 0.11
# wheel (the last two in a debootstrap root under build/, made on first use; the wheel lane tests
# the installed package); writes the table in docs/compatibility.md. Needs root (debootstrap,
# chroot, mounts).
test-compat: setup
	tools/compat/run.sh

# The main job: the collapsed and the scattered cube (paper Fig. 5) under two MPI ranks, into
# results/<scene>/ (XDMF for ParaView, step log, summary.json); each prints its summary.
demo: setup
	$(MPIEXEC) -n 2 $(PYTHON) -m dolfinx_invertible run collapse --out results/collapse
	$(MPIEXEC) -n 2 $(PYTHON) -m dolfinx_invertible run scatter --out results/scatter

# One picture per gallery entry (tools/gallery.py: runs each scene with the command the README
# shows, renders it with ParaView into docs/gallery/, rewrites the README's gallery table).
.PHONY: gallery
gallery: setup
	$(PYTHON) tools/gallery.py

# Quick sizes of every benchmark, JSON in output/bench/ (full sizes: README, Performance).
BENCH_JSON := output/bench

bench: setup
	$(PYTHON) -m dolfinx_invertible bench material
	mkdir -p $(BENCH_JSON)
	$(PYTHON) -m dolfinx_invertible bench assembly --json $(BENCH_JSON)/assembly.json
	$(PYTHON) -m dolfinx_invertible bench points --json $(BENCH_JSON)/points.json
	$(PYTHON) -m dolfinx_invertible bench solve --json $(BENCH_JSON)/solve.json
	$(PYTHON) -m dolfinx_invertible bench scaling --json $(BENCH_JSON)/scaling.json
	$(PYTHON) -m dolfinx_invertible bench memory --json $(BENCH_JSON)/memory.json
	$(PYTHON) -m dolfinx_invertible bench compile --race-repeats 1 --json $(BENCH_JSON)/compile.json

lint: $(VENV)/.installed
	[ "$$($(VENV)/bin/ruff --version 2>/dev/null)" = "ruff $(RUFF_VERSION)" ] || \
	  $(PYTHON) -m pip install -q ruff==$(RUFF_VERSION)
	$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .

# numba's disk cache is keyed on each function's own file, not on the functions it calls: after
# editing the package, drop it so nothing stale gets loaded.
clean-cache:
	find dolfinx_invertible -name '*.nbi' -delete -o -name '*.nbc' -delete
	rm -f $(NUMBA_CACHE_KEY)

clean: clean-cache
	rm -rf $(VENV) output *.egg-info
