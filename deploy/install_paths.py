#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""meson install step: point the installed systemd unit and Slurm script at
the installed gearsimd (the checkout's copies name /usr/local/bin and the
build tree). Arguments: UNIT SLURM BINDIR (absolute, without DESTDIR)."""
import os
import re
import sys


def dest(path):
    d = os.environ.get("DESTDIR", "")
    return os.path.join(d, path.lstrip("/")) if d else path


def rewrite(path, pattern, repl):
    p = dest(path)
    with open(p) as f:
        text = f.read()
    new, n = re.subn(pattern, repl, text, flags=re.M)
    if n == 0:
        sys.exit(f"install_paths.py: no gearsimd path to set in {p}")
    with open(p, "w") as f:
        f.write(new)


def main():
    unit, slurm, bindir = sys.argv[1:4]
    daemon = os.path.join(bindir, "gearsimd")
    rewrite(unit, r"^(ExecStart=.*?)\S*/gearsimd(?=\s|$)", lambda m: m.group(1) + daemon)
    rewrite(slurm, r"^(GEARSIMD=\$\{GEARSIMD:-)[^}]*(\})", lambda m: m.group(1) + daemon + m.group(2))


if __name__ == "__main__":
    main()
