#!/usr/bin/env bash
# Run the full test suite on each supported DOLFINx, serially and on two MPI ranks:
#   host    Debian bookworm's python3-dolfinx-real 0.5.2 (the repo's .venv; `make setup` first);
#           when `make test` has just run on this very tree, its counts are taken instead
#   trixie  Debian trixie's python3-dolfinx-real 0.9, in a debootstrap root
#   wheel   the PyPI wheel dolfinx-solver-real 0.11, in a venv on the trixie root's Python
# then record the counts in tools/compat/results.json and the table in docs/compatibility.md.
# The host and trixie lanes test the source tree; the wheel lane tests this package installed
# from its built wheel into the venv's site-packages, mounted read-only (as for a user whose
# site-packages is not writable: numba then caches in ~/.cache/numba). The trixie and wheel
# lanes run side by side.
#
# Environment: COMPAT_LANES (default "host trixie wheel"), COMPAT_ROOT (default
# build/compat/trixie), COMPAT_PYTEST_ARGS (extra pytest arguments, e.g. test ids, split on
# spaces), COMPAT_RUN_TIMEOUT and COMPAT_MPI_RUN_TIMEOUT (seconds per serial and per MPI run,
# default 2700 and 900). Exits non-zero if any run failed, after recording all of them.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
root=${COMPAT_ROOT:-$repo/build/compat/trixie}
root=$(realpath -m "$root")
lanes=${COMPAT_LANES:-host trixie wheel}
results=$repo/build/compat/results
# --durations: the slowest tests of each lane in the log, where a lane's time goes.
pytest_flags=(-q -p no:cacheprovider -p pytest_counts --durations=15)
read -ra extra_arguments <<< "${COMPAT_PYTEST_ARGS:-}"
pytest_flags+=("${extra_arguments[@]}")
# Serially, one pytest worker per core (each test file on one worker), as `make test` does; but
# the DOLFINx lanes run side by side, one pytest process each, when there are two of them.
# nproc counts OMP_NUM_THREADS, which make sets to 1: the cores are counted without it.
serial_flags=(-n "$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc)" --dist loadfile)
side_by_side=0
# A hung run must not eat the CI budget (90 min), but a slow machine must not fail a lane: the
# wheel lane's serial run, one process beside the trixie lane, took 16 min on one machine and
# over 30 on a machine half as fast. The timeout interrupts (SIGINT) rather than terminates, so
# pytest still prints its summary: the failures so far and the slowest tests. The MPI runs take
# a minute or two, so theirs is shorter.
run_timeout=${COMPAT_RUN_TIMEOUT:-2700}
mpi_run_timeout=${COMPAT_MPI_RUN_TIMEOUT:-900}

# shellcheck source=tools/compat/chroot.sh
source "$here/chroot.sh"

"$here/build-root.sh" "$root"

compat_mount "$root" "$repo"
trap 'kill $(jobs -p) 2>/dev/null || true; wait || true; compat_unmount_all "$root"' EXIT
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
  local counts=$results/$lane-$mode.counts launcher=() flags=("${pytest_flags[@]}")
  local limit=$run_timeout
  [ "$mode" = mpi ] && limit=$mpi_run_timeout
  local timeout_command=(timeout -s INT -k 120 "$limit")
  if [ "$mode" = serial ] && { [ "$lane" = host ] || [ "$side_by_side" = 0 ]; }; then
    flags+=("${serial_flags[@]}")
  fi
  case $lane in
    host)
      [ "$mode" = mpi ] && launcher=(mpirun -n 2)
      (cd "$repo" && env "${common_env[@]}" COMPAT_COUNTS="$counts" PYTHONPATH="$here" \
        "${timeout_command[@]}" "${launcher[@]}" "$repo/.venv/bin/python" -m pytest "${flags[@]}")
      ;;
    trixie | wheel)
      local python=/usr/bin/python3 lane_env=()
      # The report studies and the main job's demo run scenes that the scene tests cover
      # already, for minutes, and the full model x extension matrix is mostly compilation:
      # leave them to the host lane, run every model and every extension at least once here
      # (tests/conftest.py).
      flags+=(-m "not study and not demo_job" --chains covering)
      if [ "$lane" = wheel ]; then
        python=$wheel_venv/bin/python
        # The venv as if activated: the wheel brings its own MPICH, so its mpiexec/mpirun (also
        # for tests that start MPI children), not trixie's OpenMPI.
        lane_env=(VIRTUAL_ENV="$wheel_venv" PATH="$wheel_venv/bin:/usr/sbin:/usr/bin:/sbin:/bin")
        [ "$mode" = mpi ] && launcher=("$wheel_venv/bin/mpiexec" -n 2)
      else
        [ "$mode" = mpi ] && launcher=(mpirun -n 2)
      fi
      local source_env=(NUMBA_CACHE_DIR="$(numba_cache "$lane")" PYTHONPATH=/repo:/repo/tools/compat)
      if [ "$lane" = wheel ]; then
        # PYTHONSAFEPATH (inherited by child processes): the working directory /repo stays off
        # sys.path, so the installed copy is imported; numba picks its own cache folder.
        source_env=(PYTHONSAFEPATH=1 PYTHONPATH=/repo/tools/compat)
      fi
      COMPAT_CWD=/repo compat_chroot "$root" "${common_env[@]}" "${lane_env[@]}" \
        COMPAT_COUNTS="/repo/${counts#"$repo/"}" "${source_env[@]}" \
        "${timeout_command[@]}" "${launcher[@]}" "$python" -m pytest "${flags[@]}"
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
site_packages=$(compat_chroot "$root" "$wheel_venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')

# install_wheel: build this package's wheel from a copy of the tree (nothing is built inside the
# repository), install it into the wheel venv (not editable), and mount the installed package
# read-only; checks that the tests will import it from there.
install_wheel() {
  local stage=$root/tmp/compat-source
  rm -rf "$stage" && mkdir -p "$stage"
  (cd "$repo" && tar -cf - --exclude=__pycache__ pyproject.toml README.md dolfinx_invertible) |
    tar -xf - -C "$stage"
  compat_chroot "$root" PIP_CERT=/usr/local/share/compat-host-ca/ca-certificates.crt \
    "$wheel_venv/bin/pip" install -q --no-deps --force-reinstall /tmp/compat-source
  local installed=$root$site_packages/dolfinx_invertible
  mount --bind "$installed" "$installed"
  mount -o remount,bind,ro "$installed"
  compat_readonly_mounts+=("$installed")
  rm -rf "$root/root/.cache/numba"
  local where
  where=$(COMPAT_CWD=/repo compat_chroot "$root" "$wheel_venv/bin/python" -P -c \
    'import dolfinx_invertible, os; print(os.path.dirname(dolfinx_invertible.__file__))')
  if [ "$where" != "$site_packages/dolfinx_invertible" ]; then
    echo "error: the wheel lane imports dolfinx_invertible from $where" >&2
    return 1
  fi
  echo "wheel lane: dolfinx_invertible $(compat_chroot "$root" "$wheel_venv/bin/python" -P -c \
    'import dolfinx_invertible; print(dolfinx_invertible.__version__)') installed read-only at $where"
}

# numba_cached_files: how many numba index files the read-only install's lane wrote.
numba_cached_files() {
  find "$root/root/.cache/numba" -name '*.nbi' 2>/dev/null | wc -l
}

# reuse_host_results MODE: take the host lane's counts from `make test` (tools/compat/record.sh)
# if that run tested this very tree and no test arguments narrow this one.
reuse_host_results() {
  local mode=$1 folder=$repo/build/compat/host
  [ -z "${COMPAT_PYTEST_ARGS:-}" ] || return 1
  [ -f "$folder/host-$mode.key" ] && [ -f "$folder/host-$mode.status.json" ] || return 1
  [ "$(cat "$folder/host-$mode.key")" = "$("$here/source-key.sh")" ] || return 1
  cp "$folder/host-$mode".status.json "$folder/host-$mode".counts.* "$results/" 2>/dev/null ||
    return 1
  echo "host lane: the results of make test on this tree ($(cat "$folder/host-$mode.status.json"))"
}

exit_status() {
  python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["exitstatus"])' "$1"
}

# run_lane LANE: the lane's serial and MPI runs; non-zero if any failed.
run_lane() {
  local lane=$1 failed=0 mode start status cached
  for mode in serial mpi; do
    echo "=== $lane ($(cat "$results/$lane.versions.json")): $mode"
    if [ "$lane" = host ] && reuse_host_results "$mode"; then
      [ "$(exit_status "$results/host-$mode.status.json")" = 0 ] || failed=1
      continue
    fi
    start=$(date +%s)
    status=0
    run_pytest "$lane" "$mode" || status=$?
    printf '{"exitstatus": %d, "seconds": %d}\n' "$status" "$(($(date +%s) - start))" \
      > "$results/$lane-$mode.status.json"
    [ "$status" = 0 ] || failed=1
  done
  if [ "$lane" = wheel ]; then
    cached=$(numba_cached_files)
    echo "wheel lane: numba cached $cached functions in ~/.cache/numba (site-packages read-only)"
    [ "$cached" -gt 0 ] || failed=1
  fi
  return "$failed"
}

failed=0
dolfinx_lanes=()
for lane in $lanes; do
  describe "$lane" > "$results/$lane.versions.json" || echo "{}" > "$results/$lane.versions.json"
  if [ "$lane" = host ]; then
    run_lane host || failed=1
  elif [ "$lane" = wheel ] && ! install_wheel; then
    failed=1
  else
    dolfinx_lanes+=("$lane")
  fi
done
# The other DOLFINx versions side by side: from a cold numba cache a lane is mostly compilation,
# which two single processes share between the cores better than one lane on two workers.
[ "${#dolfinx_lanes[@]}" -gt 1 ] && side_by_side=1
pids=()
for lane in "${dolfinx_lanes[@]}"; do
  run_lane "$lane" > "$results/$lane.log" 2>&1 &
  pids+=("$!")
done
for index in "${!pids[@]}"; do
  wait "${pids[$index]}" || failed=1
  cat "$results/${dolfinx_lanes[$index]}.log"
done

python3 "$here/report.py" "$results" "$repo/tools/compat/results.json" \
  "$repo/docs/compatibility.md" $lanes
exit "$failed"
