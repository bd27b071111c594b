# SPDX-License-Identifier: MIT
"""Where the connection file lives and how it is read (docs/PROTOCOL.md)."""
import json
import os

from .errors import GearsimError


def default_connection_file():
    """$XDG_RUNTIME_DIR/gearsim/gearsimd.json if XDG_RUNTIME_DIR is set, else
    /tmp/gearsim-<uid>/gearsimd.json (the daemon's own default)."""
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg:
        return os.path.join(xdg, "gearsim", "gearsimd.json")
    return os.path.join("/tmp", f"gearsim-{os.getuid()}", "gearsimd.json")


def read_connection_file(path=None):
    """Parse the connection file; GearsimError("not_found" | "bad_json") if unusable."""
    path = path or default_connection_file()
    try:
        with open(path) as f:
            info = json.load(f)
    except FileNotFoundError:
        raise GearsimError("not_found", f"no connection file at {path}: is gearsimd running?") from None
    except (OSError, ValueError) as e:
        raise GearsimError("bad_json", f"cannot read connection file {path}: {e}") from None
    if not isinstance(info, dict) or not isinstance(info.get("command"), str):
        raise GearsimError("bad_json", f"connection file {path} has no 'command' endpoint")
    if info.get("protocol", 1) != 1:
        raise GearsimError("unsupported_version",
                           f"daemon speaks protocol {info.get('protocol')}, this client speaks 1")
    info["_path"] = path
    return info
