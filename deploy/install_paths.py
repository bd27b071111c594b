#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""meson install step: point the installed systemd unit, Slurm script and
env.sh at the installed gearsimd and loopback shim (the checkout's copies
name /usr/local and the build tree). Arguments: UNIT SLURM ENV_SH BINDIR
SHIM (absolute, without DESTDIR)."""
import os
import re
import sys


def dest(path):
    d = os.environ.get("DESTDIR", "")
    return os.path.join(d, path.lstrip("/")) if d else path


def rewrite(path, *subs):
    """Each (pattern, replacement) of `subs` must match in the file."""
    p = dest(path)
    with open(p) as f:
        text = f.read()
    for pattern, repl in subs:
        text, n = re.subn(pattern, repl, text, flags=re.M)
        if n == 0:
            sys.exit(f"install_paths.py: nothing matches {pattern!r} in {p}")
    with open(p, "w") as f:
        f.write(text)


def default_of(var):
    """A shell line `...VAR=${VAR:-default}` with its default replaced."""
    return r"^(\s*(?:export )?\w+=\$\{" + var + r":-)[^}]*(\})"


def main():
    unit, slurm, env_sh, bindir, shim = sys.argv[1:6]
    daemon = os.path.join(bindir, "gearsimd")
    rewrite(unit, (r"^(ExecStart=.*?)\S*/gearsimd(?=\s|$)", lambda m: m.group(1) + daemon),
            (r"^(Environment=LD_PRELOAD=)\S*/gearsim-loopback\.so$", lambda m: m.group(1) + shim))
    rewrite(slurm, (default_of("GEARSIMD"), lambda m: m.group(1) + daemon + m.group(2)),
            (default_of("GEARSIM_LOOPBACK_PRELOAD"), lambda m: m.group(1) + shim + m.group(2)))
    rewrite(env_sh, (default_of("GEARSIM_LOOPBACK_PRELOAD"), lambda m: m.group(1) + shim + m.group(2)))


if __name__ == "__main__":
    main()
