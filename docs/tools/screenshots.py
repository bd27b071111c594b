#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""Screenshots of three pages of the built manual, rendered by headless
Chromium (Debian's `chromium`), into docs/img:

  screenshot_front.png      the manual's front page
  screenshot_tutorial.png   the first tutorial at its DTE plot
  screenshot_validation.png the validation report

usage: screenshots.py [--html DIR] [--out DIR]
  --html DIR  the built manual (default build/manual: `ninja -C build manual`)
  --out DIR   where the PNG files go (default docs/img)"""
import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SHOTS = [  # (file, page, fragment, window height)
    ("screenshot_front.png", "index.html", "", 1000),
    ("screenshot_tutorial.png", "tutorials/pair_dte.html", "plot-the-dynamic-transmission-error", 1500),
    ("screenshot_validation.png", "validation/index.html", "", 1300),
]


def main():
    args = sys.argv[1:]
    html = os.path.join(ROOT, "build", "manual")
    out = os.path.join(ROOT, "docs", "img")
    if "--html" in args:
        html = os.path.abspath(args[args.index("--html") + 1])
    if "--out" in args:
        out = os.path.abspath(args[args.index("--out") + 1])
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if not exe:
        print("chromium not found (Debian package chromium; deploy/install-deps.sh installs it)")
        return 1
    failed = 0
    with tempfile.TemporaryDirectory(prefix="gearsim-shots-") as profile:
        for name, page, frag, height in SHOTS:
            path = os.path.join(html, page)
            if not os.path.isfile(path):
                print(f"missing page {path}: build the manual first (ninja -C build manual)")
                failed += 1
                continue
            url = "file://" + path
            if frag:   # a copy of the page beside it that starts at the fragment's section (title kept)
                with open(path) as f:
                    text = f.read()
                path = os.path.join(os.path.dirname(path), ".screenshot-" + os.path.basename(path))
                script = ("<script>document.addEventListener('DOMContentLoaded', function () {"
                          f"var e = document.getElementById('{frag}');"
                          "for (var p = e && e.previousElementSibling; p; p = p.previousElementSibling)"
                          " if (!/^H1$/.test(p.tagName)) p.style.display = 'none'; });</script>")
                with open(path, "w") as f:
                    f.write(text.replace("</body>", script + "</body>"))
                url = "file://" + path
            dst = os.path.join(out, name)
            cmd = [exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                   "--force-device-scale-factor=1", f"--user-data-dir={profile}",
                   f"--window-size=1280,{height}", f"--screenshot={dst}", url]
            cmd.insert(-1, "--virtual-time-budget=3000")
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
            if frag:
                os.unlink(path)
            ok = r.returncode == 0 and os.path.isfile(dst) and os.path.getsize(dst) > 10000
            print(("wrote " if ok else "FAILED ") + os.path.relpath(dst, ROOT) + f" ({url})")
            failed += not ok
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
