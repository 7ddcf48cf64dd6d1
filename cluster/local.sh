#!/usr/bin/env bash
# A real multi-process Dask cluster on loopback: one `dask scheduler` and N `dask worker`
# processes, one thread each, with the /daskrad dashboard page. Runs in the foreground until
# Ctrl-C / SIGTERM, then stops its processes.
#
#   cluster/local.sh [DIR] [NWORKERS]        # DIR holds scheduler.json and the logs
#   daskrad run scenes/cornell_box.obj --scheduler "$(cluster/address.sh DIR)" -o "$PWD/out/cb.exr"
#
# Environment: DASK (the dask CLI, default `dask` on PATH), PORT (scheduler port, default 0 =
# any free port), DASHBOARD (default 127.0.0.1:0: loopback only; any free port).
set -euo pipefail

dir="${1:-${TMPDIR:-/tmp}/daskrad-cluster}"
nworkers="${2:-2}"
dask="${DASK:-dask}"
mkdir -p "$dir"
rm -f "$dir/scheduler.json"

# The scheduler serves /daskrad when its HTTP routes include daskrad's page (the defaults
# first, so the standard dashboard keeps working).
export DASK_DISTRIBUTED__SCHEDULER__HTTP__ROUTES="['distributed.http.scheduler.prometheus', \
'distributed.http.scheduler.info', 'distributed.http.scheduler.json', \
'distributed.http.health', 'distributed.http.proxy', 'distributed.http.statics', \
'daskrad.distributed.dashboard']"
# numba's threads match the worker's single thread: N workers share N cores
export NUMBA_NUM_THREADS=1

pids=()
stop() {
    trap - EXIT INT TERM
    for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
    wait 2>/dev/null || true
}
trap stop EXIT INT TERM

"$dask" scheduler --host 127.0.0.1 --port "${PORT:-0}" \
    --dashboard-address "${DASHBOARD:-127.0.0.1:0}" \
    --scheduler-file "$dir/scheduler.json" >"$dir/scheduler.log" 2>&1 &
pids+=($!)

for _ in $(seq 100); do [[ -s "$dir/scheduler.json" ]] && break; sleep 0.1; done
[[ -s "$dir/scheduler.json" ]] || { echo "scheduler did not start; see $dir/scheduler.log" >&2; exit 1; }

"$dask" worker --scheduler-file "$dir/scheduler.json" --nworkers "$nworkers" --nthreads 1 \
    --host 127.0.0.1 --dashboard-address 127.0.0.1:0 >"$dir/workers.log" 2>&1 &
pids+=($!)

echo "scheduler $(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["address"])' \
    "$dir/scheduler.json"), $nworkers workers; logs in $dir"
wait
