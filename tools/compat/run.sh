#!/usr/bin/env bash
# Run the full test suite on each supported DOLFINx, serially and on two MPI ranks:
#   host    Debian bookworm's python3-dolfinx-real 0.5.2 (the repo's .venv; `make setup` first)
#   trixie  Debian trixie's python3-dolfinx-real 0.9, in a debootstrap root
#   wheel   the PyPI wheel dolfinx-solver-real 0.11, in a venv on the trixie root's Python
# then record the counts in tools/compat/results.json and the README table.
#
# Environment: COMPAT_LANES (default "host trixie wheel"), COMPAT_ROOT (default
# build/compat/trixie). Exits non-zero if any run failed, after recording all of them.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
root=${COMPAT_ROOT:-$repo/build/compat/trixie}
root=$(realpath -m "$root")
lanes=${COMPAT_LANES:-host trixie wheel}
results=$repo/build/compat/results
pytest_flags=(-q -p no:cacheprovider -p pytest_counts)
# A hung MPI run must not eat the CI budget.
run_timeout=${COMPAT_RUN_TIMEOUT:-1800}

# shellcheck source=tools/compat/chroot.sh
source "$here/chroot.sh"

"$here/build-root.sh" "$root"

compat_mount "$root" "$repo"
trap 'compat_unmount_all "$root"' EXIT
# A signal ends the script through exit, so the EXIT trap unmounts in every case.
trap 'exit 130' INT
trap 'exit 143' TERM

rm -rf "$results"
mkdir -p "$results"

# numba's disk cache is keyed per file, not per callee: key each lane's cache on the whole
# package source, so an edit anywhere starts a fresh cache and an unchanged tree reuses it.
source_key=$(cd "$repo" && find dolfinx_invertible -name '*.py' -print0 | sort -z |
  xargs -0 sha256sum | sha256sum | cut -c1-16)

common_env=(
  OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 PYTHONDONTWRITEBYTECODE=1
  OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
)

# run_pytest LANE MODE: pytest over the whole suite in LANE, serially or on two MPI ranks.
run_pytest() {
  local lane=$1 mode=$2
  local counts=$results/$lane-$mode.counts launcher=()
  case $lane in
    host)
      [ "$mode" = mpi ] && launcher=(mpirun -n 2)
      (cd "$repo" && env "${common_env[@]}" COMPAT_COUNTS="$counts" PYTHONPATH="$here" \
        timeout "$run_timeout" "${launcher[@]}" "$repo/.venv/bin/python" -m pytest \
        "${pytest_flags[@]}")
      ;;
    trixie | wheel)
      local python=/usr/bin/python3 lane_env=()
      if [ "$lane" = wheel ]; then
        python=$wheel_venv/bin/python
        # The venv as if activated: the wheel brings its own MPICH, so its mpiexec/mpirun (also
        # for tests that start MPI children), not trixie's OpenMPI.
        lane_env=(VIRTUAL_ENV="$wheel_venv" PATH="$wheel_venv/bin:/usr/sbin:/usr/bin:/sbin:/bin")
        [ "$mode" = mpi ] && launcher=("$wheel_venv/bin/mpiexec" -n 2)
      else
        [ "$mode" = mpi ] && launcher=(mpirun -n 2)
      fi
      COMPAT_CWD=/repo compat_chroot "$root" "${common_env[@]}" "${lane_env[@]}" \
        COMPAT_COUNTS="/repo/${counts#"$repo/"}" NUMBA_CACHE_DIR="$(numba_cache "$lane")" \
        PYTHONPATH=/repo:/repo/tools/compat \
        timeout "$run_timeout" "${launcher[@]}" "$python" -m pytest "${pytest_flags[@]}"
      ;;
  esac
}

# numba_cache LANE: the lane's numba cache folder inside the root for this source tree; older
# trees' caches are dropped.
numba_cache() {
  local folder=/var/cache/compat-numba/$1 entry
  mkdir -p "$root$folder"
  for entry in "$root$folder"/*; do
    [ -e "$entry" ] && [ "$(basename "$entry")" != "$source_key" ] && rm -rf "$entry"
  done
  echo "$folder/$source_key"
}

# describe LANE: one JSON object with the versions the lane runs.
describe() {
  local lane=$1 python
  local probe='import json, platform, sys
try:
    import dolfinx_solver  # noqa: F401
except ImportError:
    pass
import dolfinx, numba, numpy
print(json.dumps({"dolfinx": dolfinx.__version__, "python": platform.python_version(),
                  "numba": numba.__version__, "numpy": numpy.__version__}))'
  case $lane in
    host) "$repo/.venv/bin/python" -c "$probe" ;;
    trixie) compat_chroot "$root" /usr/bin/python3 -c "$probe" ;;
    wheel) compat_chroot "$root" "$wheel_venv/bin/python" -c "$probe" ;;
  esac
}

wheel_venv=/opt/dolfinx-wheel
failed=0
for lane in $lanes; do
  describe "$lane" > "$results/$lane.versions.json" || echo "{}" > "$results/$lane.versions.json"
  for mode in serial mpi; do
    echo "=== $lane ($(cat "$results/$lane.versions.json")): $mode"
    start=$(date +%s)
    status=0
    run_pytest "$lane" "$mode" || status=$?
    printf '{"exitstatus": %d, "seconds": %d}\n' "$status" "$(($(date +%s) - start))" \
      > "$results/$lane-$mode.status.json"
    [ "$status" = 0 ] || failed=1
  done
done

python3 "$here/report.py" "$results" "$repo/tools/compat/results.json" "$repo/README.md" $lanes
exit "$failed"
