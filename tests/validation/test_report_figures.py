#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""The validation report's figures rerun by the commands the report gives
(docs/validation/, docs/data/validation.py): every cheap figure is rerun and
each cell of its table compared with the stored file the page includes, so the
report cannot drift from what the code computes. Long mode only
(GEARSIM_LONG=1: several CPU minutes); otherwise skipped (exit 77).

The comparison itself is docs/data/validation.py `check`: text cells equal,
numbers within the figure's tolerance (`validation.py list` prints them). A
figure whose command fails, prints nothing parsable, or gives another number
fails the test. The stored tables must also be complete: every figure the
pages include has its file, and every page of the report includes its table.
"""
import os
import re
import subprocess
import sys

SRC = os.environ.get("GEARSIM_SOURCE_ROOT",
                     os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")))
SCRIPT = os.path.join(SRC, "docs", "data", "validation.py")


def main():
    pages = os.path.join(SRC, "docs", "validation")
    included = {}
    for name in sorted(os.listdir(pages)):
        if name.endswith(".md"):
            text = open(os.path.join(pages, name)).read()
            for f in re.findall(r":file: \.\./data/(validation_\w+)\.csv", text):
                included[f[len("validation_"):]] = name
    failures = []
    for fig, page in included.items():
        if not os.path.isfile(os.path.join(SRC, "docs", "data", "validation_%s.csv" % fig)):
            failures.append("%s includes docs/data/validation_%s.csv, which is missing" % (page, fig))
    print("%s: the report's pages include %d stored tables" % ("FAIL" if failures else "ok", len(included)))
    if os.environ.get("GEARSIM_LONG") != "1":
        print("# skipped: the figures are rerun with GEARSIM_LONG=1 only")
        return 1 if failures else 77
    r = subprocess.run([sys.executable, SCRIPT, "check"], cwd=SRC, stdout=subprocess.PIPE,
                       stderr=subprocess.STDOUT, text=True)
    print(r.stdout)
    checked = re.findall(r"^(ok|FAIL): (\w+)$", r.stdout, re.M)
    missing = sorted(set(included) - {n for _, n in checked})
    if r.returncode != 0:
        failures.append("validation.py check exited %d" % r.returncode)
    if missing:
        failures.append("not rerun: %s" % ", ".join(missing))
    for f in failures:
        print("FAIL: " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
