#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# ParaView check of the field records (optional, not in deploy/test.sh: the
# paraview package is ~450 MB). Installs Debian's paraview (and xvfb) when
# pvbatch is missing, records the contact_impact scene with field snapshots
# on a 2-rank daemon, opens the record's XDMF file with the reader ParaView
# picks by default and renders von Mises stress on the deformed gears at
# three instants (first impact, teeth apart, second impact) into
# docs/img/paraview_contact_impact_{1,2,3}.png. Prints what ParaView read.
#   deploy/check-paraview.sh [OUT_DIR]      (default docs/img)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
out=${1:-docs/img}
if ! command -v pvbatch >/dev/null || ! dpkg-query -W python3-paraview >/dev/null 2>&1; then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends paraview python3-paraview xvfb xauth >/dev/null
fi
. deploy/env.sh
build=${GEARSIM_BUILD:-build}
if [ ! -x "$build/src/daemon/gearsimd" ]; then
  [ -f "$build/build.ninja" ] || meson setup "$build" >/dev/null
  ninja -C "$build" >/dev/null
fi
tmp=$(mktemp -d /tmp/gearsim-paraview.XXXXXX)
conn=$tmp/gearsimd.json
gearctl=(/usr/bin/python3 clients/python/gearctl --connection-file "$conn")
cleanup() {
  [ -f "$conn" ] && "${gearctl[@]}" shutdown >/dev/null 2>&1 || true
  wait 2>/dev/null || true
  rm -rf "$tmp"
}
trap cleanup EXIT
mpirun -n 2 "$build/src/daemon/gearsimd" --connection-file "$conn" --data-dir "$tmp/data" 2>"$tmp/daemon.log" &
# 1 ms of the impact experiment: frames every 200 steps of 1 us.
"${gearctl[@]}" --wait 60 run builtin:contact_impact --until 0.001 --record "$tmp/contact_impact.h5" | tail -n 2
mkdir -p "$out"
args=(deploy/paraview_render.py "$tmp/contact_impact.xmf" "$out/paraview_contact_impact" 0.0002 0.0004 0.0008)
# pvbatch renders off screen where ParaView was built for it; otherwise on a
# virtual X server.
if ! pvbatch --force-offscreen-rendering "${args[@]}" 2>"$tmp/pvbatch.log"; then
  echo "pvbatch off screen failed ($(tail -n 1 "$tmp/pvbatch.log")); trying under xvfb-run"
  xvfb-run -a -s "-screen 0 1280x1024x24" pvbatch "${args[@]}"
fi
ls -l "$out"/paraview_contact_impact_*.png
