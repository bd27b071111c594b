#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The main job end to end: install, build, start gearsimd under mpirun with
# the embedded planetary train, drive it from the Python client (ramp moment
# on the sun, brake on the carrier, 0.2 s), show live telemetry, write an
# HDF5 record and a PNG plot, and shut the daemon down cleanly.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
deploy/install-deps.sh
. deploy/env.sh
. deploy/progress.sh
build=${GEARSIM_BUILD:-build}
gs_build "$build"
out=${GEARSIM_OUT:-$root/out}
mkdir -p "$out"
chmod 700 "$out"   # the connection file in it holds the client key pair
rm -f "$out/gearsimd.json"
ranks=${GEARSIM_RANKS:-2}
echo "starting gearsimd under mpirun -n $ranks (log: $out/gearsimd.log)"
# mpirun's own listeners on loopback too (deploy/env.sh, docs/RELIABILITY.md):
# this build's shim (env.sh's mpirun function would preload the default build's)
LD_PRELOAD="$build/src/daemon/gearsim-loopback.so" command mpirun -n "$ranks" "$build/src/daemon/gearsimd" --connection-file "$out/gearsimd.json" \
  --data-dir "$out" 2>"$out/gearsimd.log" &
daemon=$!
cleanup() { kill "$daemon" 2>/dev/null || true; }
trap cleanup EXIT
for _ in $(seq 100); do [ -f "$out/gearsimd.json" ] && break; sleep 0.1; done
[ -f "$out/gearsimd.json" ] || { cat "$out/gearsimd.log"; echo "the daemon did not start"; exit 1; }
gearctl=(/usr/bin/python3 clients/python/gearctl --connection-file "$out/gearsimd.json")
"${gearctl[@]}" run builtin:planetary --until 0.2 --record "$out/demo.h5" --telemetry "$out/demo.jsonl" --live
"${gearctl[@]}" plot "$out/demo.h5" -o "$out/demo.png"
"${gearctl[@]}" shutdown
wait "$daemon" || true
trap - EXIT
echo "record: $out/demo.h5"
echo "plot:   $out/demo.png"
