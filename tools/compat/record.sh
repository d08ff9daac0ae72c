#!/usr/bin/env bash
# record.sh MODE COMMAND...: run a pytest COMMAND of `make test` on the host and keep its counts,
# so that `make test-compat` reports the host lane from this run instead of running the suite a
# second time (tools/compat/run.sh reuses them when the tree has not changed since).
#   MODE     serial or mpi
#   COMMAND  the pytest command line (the counts plugin is added here)
# Writes build/compat/host/host-MODE.{status.json,counts.RANK,key}; exits with COMMAND's status.
set -uo pipefail

here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
mode=$1
shift
folder=$repo/build/compat/host
mkdir -p "$folder"
rm -f "$folder/host-$mode".*

start=$(date +%s)
COMPAT_COUNTS="$folder/host-$mode.counts" PYTHONPATH="$here${PYTHONPATH:+:$PYTHONPATH}" \
  "$@" -p pytest_counts
status=$?
printf '{"exitstatus": %d, "seconds": %d}\n' "$status" "$(($(date +%s) - start))" \
  > "$folder/host-$mode.status.json"
"$here/source-key.sh" > "$folder/host-$mode.key"
exit "$status"
