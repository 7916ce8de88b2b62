#!/usr/bin/env bash
# A drltg sweep on a two-node Ray cluster started on this machine and bound to the loopback address only:
#   bash examples/ray_two_nodes.sh [SPEC] [OUT] [MORE drltg sweep OPTIONS]
#   (SPEC=examples/sweeps/ray-two-nodes.yaml, OUT=runs/ray-two-nodes by default)
# Starts a head node (`ray start --head --node-ip-address=127.0.0.1 --num-cpus=1`, no dashboard) and a
# worker node that joins it (`ray start --address=127.0.0.1:PORT --node-ip-address=127.0.0.1 --num-cpus=1`),
# runs `drltg sweep SPEC --out OUT --backend ray --address 127.0.0.1:PORT`, and stops both nodes when it
# ends, also on an error, Ctrl-C or SIGTERM (which first stops the sweep: its Ray tasks are cancelled and
# their runs keep their checkpoints). Running it again resumes the sweep (complete runs are skipped).
#
# Each node runs in a session of its own, so that exactly its processes are stopped (`ray stop` would stop
# every Ray node this user runs on the machine); its pid is in TMP/{head,worker}.sid and its files under
# TMP/{head,worker}/. On Linux `ray start` replaces a loopback --node-ip-address by the machine's address,
# and the node's servers then listen on every interface; `ray start` is run here through a few lines of
# Python that keep 127.0.0.1, so every server of the cluster listens on 127.0.0.1 only. The cluster
# requires a token (Ray's token authentication) made afresh for it: any local user could otherwise use it.
# Environment: RAY_PORT (the head's port, 6390; Ray's client server takes the next one), PYTHON (python3,
# with Ray), DRLTG (the command, drltg), RAY_TMP (default: a fresh /tmp/drltg-ray.*, removed after a
# successful sweep; short, since Ray's socket paths must stay under 108 bytes).
set -euo pipefail
SPEC=${1:-examples/sweeps/ray-two-nodes.yaml}
OUT=${2:-runs/ray-two-nodes}
shift $(($# < 2 ? $# : 2))
PORT=${RAY_PORT:-6390}
PYTHON=${PYTHON:-python3}
DRLTG=${DRLTG:-drltg}
TMP=${RAY_TMP:-}
[ -z "$TMP" ] && TMP=$(mktemp -d /tmp/drltg-ray.XXXXXX) && made_tmp=1
export RAY_AUTH_MODE=token
RAY_AUTH_TOKEN=$(od -An -tx1 -N32 /dev/urandom | tr -d ' \n')
export RAY_AUTH_TOKEN
echo "ray: two nodes on 127.0.0.1:$PORT, their files in $TMP"

ray_start() {  # NODE ARGS...: `ray start ARGS` in a new session, keeping a loopback node address
  # (Ray refuses a second node where RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0, as drltg sets for a local instance)
  if RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=1 "$PYTHON" - "$TMP/$1.sid" start "${@:2}" >"$TMP/$1.log" 2>&1 <<'PY'
import os
import sys

from ray._private import services
from ray.scripts.scripts import main

os.setsid()
with open(sys.argv[1], "w") as f:
    f.write(str(os.getpid()))
resolve = services.resolve_ip_for_localhost
services.resolve_ip_for_localhost = lambda host: host if host == "127.0.0.1" else resolve(host)
sys.argv = ["ray", *sys.argv[2:]]
sys.exit(main())
PY
  then return; fi
  echo "ray start of the $1 node failed; its output ($TMP/$1.log) ends with:" >&2
  tail -n 5 "$TMP/$1.log" >&2
  return 1
}

node_pids() {  # the running processes of a node's session
  [ -f "$TMP/$1.sid" ] &&
    ps -eo pid=,sid=,stat= | awk -v sid="$(cat "$TMP/$1.sid")" '$2 == sid && $3 !~ /^Z/ {print $1}'
  return 0
}

stop_nodes() {
  local status=$? node pids left
  for node in worker head; do
    pids=$(node_pids "$node")
    [ -n "$pids" ] && kill -TERM $pids 2>/dev/null || true
  done
  for _ in $(seq 25); do  # most of Ray's processes unwind in a second; what is left after 5 s is killed
    [ -z "$(node_pids worker; node_pids head)" ] && break
    sleep 0.2
  done
  left=$(node_pids worker; node_pids head)
  [ -n "$left" ] && kill -KILL $left 2>/dev/null || true
  echo "ray: both nodes stopped"
  if [ "$status" = 0 ] && [ -n "${made_tmp:-}" ]; then rm -rf "$TMP"; else echo "ray: the nodes' logs are in $TMP"; fi
}

sweep=
stop_sweep() {  # SIGTERM unwinds drltg sweep: it cancels its Ray tasks, whose runs keep their checkpoints
  [ -n "$sweep" ] && kill -TERM "$sweep" 2>/dev/null && wait "$sweep" || true
  exit "$1"
}
trap stop_nodes EXIT
trap 'stop_sweep 130' INT
trap 'stop_sweep 143' TERM

common=(--node-ip-address=127.0.0.1 --num-cpus=1 --object-store-memory=100000000 --disable-usage-stats
        --dashboard-agent-listen-port=0)
ray_start head --head --port="$PORT" --ray-client-server-port="$((PORT + 1))" --include-dashboard=false \
  --temp-dir="$TMP/head" "${common[@]}"
ray_start worker --address="127.0.0.1:$PORT" --temp-dir="$TMP/worker" "${common[@]}"
echo "ray: head and worker node started"
$DRLTG sweep "$SPEC" --out "$OUT" --backend ray --address "127.0.0.1:$PORT" "$@" &
sweep=$!  # in the background, so that a signal reaches this script's traps at once
wait "$sweep"
