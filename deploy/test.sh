#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Install what is missing, build, and run every test suite (unit, validation,
# integration). Ends with a line "N passed, N failed". Benchmarks are not run
# here: meson test -C build --benchmark --suite bench.
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
deploy/install-deps.sh || { echo "dependency installation failed"; echo "0 passed, 1 failed"; exit 1; }
. deploy/env.sh
. deploy/progress.sh
build=${GEARSIM_BUILD:-build}
gs_build "$build" -Dwerror=true || { echo "0 passed, 1 failed"; exit 1; }
echo "running the unit, validation and integration suites (meson test; one line per test)"
meson test -C "$build" --no-rebuild --print-errorlogs --num-processes 2 \
  --suite unit --suite validation --suite integration "$@"
status=$?
/usr/bin/python3 - "$build/meson-logs/testlog.json" <<'PY'
import json, sys
passed = failed = skipped = 0
for line in open(sys.argv[1]):
    r = json.loads(line).get("result")
    if r in ("OK", "EXPECTEDFAIL"):
        passed += 1
    elif r == "SKIP":
        skipped += 1
    else:
        failed += 1
print(f"{passed} passed, {failed} failed" + (f", {skipped} skipped" if skipped else ""))
PY
exit $status
