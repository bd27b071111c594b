# SPDX-License-Identifier: MIT
# Sourced by deploy/demo.sh and deploy/test.sh: configure and build with a
# word on what is happening and how far it is, the full output in a log.
#   gs_build BUILD_DIR [meson setup options...]
# prints "configuring ...", then "building (n/N) <step>" every 5 % of the
# build's steps, and on failure the last lines of BUILD_DIR/ninja.log.
gs_build() {
  local build=$1
  shift
  if [ ! -f "$build/build.ninja" ]; then
    echo "configuring $build (meson setup${*:+ $*})"
    mkdir -p "$build"
    if ! meson setup "$build" "$@" >"$build.setup.log" 2>&1; then
      tail -40 "$build.setup.log"
      echo "meson setup failed (log: $build.setup.log)"
      return 1
    fi
    rm -f "$build.setup.log"
  fi
  echo "building in $build (ninja; full log: $build/ninja.log)"
  local rc
  NINJA_STATUS="[%f/%t] " ninja -C "$build" 2>&1 | awk -v logf="$build/ninja.log" '
    BEGIN { next_pct = 0; printf "" > logf }
    { print > logf; fflush(logf) }
    match($0, /^\[[0-9]+\/[0-9]+\] /) {
      split(substr($0, 2, RLENGTH - 3), fr, "/")
      done = fr[1] + 0; total = fr[2] + 0
      if (total > 0 && (100 * done / total >= next_pct || done == total)) {
        printf "  building (%d/%d) %s\n", done, total, substr($0, RLENGTH + 1)
        fflush()
        while (next_pct <= 100 * done / total) next_pct += 5
      }
    }'
  rc=${PIPESTATUS[0]}
  if [ "$rc" -ne 0 ]; then
    tail -40 "$build/ninja.log"
    echo "build failed (log: $build/ninja.log)"
    return 1
  fi
  echo "built: $(grep -c '^\[' "$build/ninja.log") step(s) run, the rest up to date"
}
