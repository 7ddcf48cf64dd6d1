#!/usr/bin/env bash
# Print the scheduler address of a cluster started by cluster/local.sh DIR.
set -euo pipefail
python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["address"])' \
    "${1:-${TMPDIR:-/tmp}/daskrad-cluster}/scheduler.json"
