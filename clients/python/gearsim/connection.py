# SPDX-License-Identifier: MIT
"""Where the connection file lives and how it is read (docs/reference/protocol.md)."""
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
    if isinstance(info.get("stopped"), str):
        raise GearsimError("daemon_stopped", f"the daemon stopped: {info['stopped']}")
    if info.get("protocol", 1) != 1:
        raise GearsimError("unsupported_version",
                           f"daemon speaks protocol {info.get('protocol')}, this client speaks 1")
    info["_path"] = path
    return info


def _local_endpoint(ep):
    return isinstance(ep, str) and (ep.startswith("ipc://") or ep.startswith("tcp://127.")
                                    or ep.startswith("tcp://[::1]") or ep.startswith("tcp://localhost"))


def _pid_gone(pid):
    try:
        with open(f"/proc/{int(pid)}/stat") as f:
            st = f.read()
    except (OSError, ValueError):
        return True
    tail = st[st.rfind(")") + 1:].split()
    return not tail or tail[0] in ("Z", "X", "x")


def daemon_stopped(info):
    """Why the daemon of `info` (read_connection_file) is gone, or None while
    it runs: its connection file removed or taken by another session, the
    cause it wrote there when a rank died (`stopped`), or (for a daemon on
    this host) its process gone."""
    path = info.get("_path")
    if path:
        try:
            with open(path) as f:
                now = json.load(f)
        except FileNotFoundError:
            return f"its connection file {path} was removed"
        except (OSError, ValueError):
            now = None      # being replaced: judge by the process
        if isinstance(now, dict):
            if isinstance(now.get("stopped"), str):
                return now["stopped"]
            if now.get("session") != info.get("session"):
                return f"{path} now belongs to another daemon (session {now.get('session')})"
    pid = info.get("pid")
    if isinstance(pid, int) and pid > 0 and _local_endpoint(info.get("command")) and os.path.isdir("/proc"):
        if _pid_gone(pid):
            return f"its process {pid} is gone (killed, or a rank died and MPI aborted the job)"
    return None


# ---------------------------------------------------------------- CURVE keys
# Key files are Z85 text (docs/reference/protocol.md, "Authentication"): NAME.key holds
# `public-key = ...` and `secret-key = ...` (mode 0600), NAME.pub only the
# public key. `gearctl keys NAME` writes both.

def _key_lines(path):
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise GearsimError("io_error", f"cannot read key file {path}: {e.strerror}") from None
    out = {}
    for n, line in enumerate(lines, 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        key, val = "public-key", line
        if len(line) != 40 and "=" in line:
            key, val = (s.strip() for s in line.split("=", 1))
        if len(val) != 40:
            raise GearsimError("invalid_argument", f"{path}:{n}: not a 40-character Z85 key")
        out[key] = val
    return out


def read_key_file(path):
    """(public, secret) Z85 strings (bytes) of a `gearctl keys` .key file."""
    keys = _key_lines(path)
    if "secret-key" not in keys or "public-key" not in keys:
        raise GearsimError("invalid_argument",
                           f"{path} is not a secret key file (public-key and secret-key lines)")
    return keys["public-key"].encode(), keys["secret-key"].encode()


def write_key_files(base, force=False):
    """Write BASE.key (mode 0600) and BASE.pub with a new CURVE key pair;
    returns (pub_path, key_path, public)."""
    import zmq
    if not zmq.has("curve"):
        raise GearsimError("invalid_argument", "this libzmq has no CURVE support")
    public, secret = zmq.curve_keypair()
    key_path, pub_path = base + ".key", base + ".pub"
    for p in (key_path, pub_path):
        if os.path.exists(p) and not force:
            raise GearsimError("invalid_argument", f"{p} exists (use --force to replace it)")
    name = os.path.basename(base)
    flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC
    fd = os.open(key_path + ".tmp", flags, 0o600)
    with os.fdopen(fd, "w") as f:
        f.write(f"# gearsim CURVE key pair '{name}': keep this file private\n"
                f"public-key = {public.decode()}\nsecret-key = {secret.decode()}\n")
    os.chmod(key_path + ".tmp", 0o600)
    os.replace(key_path + ".tmp", key_path)
    with open(pub_path + ".tmp", "w") as f:
        f.write(f"# gearsim CURVE public key '{name}'\npublic-key = {public.decode()}\n")
    os.replace(pub_path + ".tmp", pub_path)
    return pub_path, key_path, public.decode()


def apply_curve(sock, info, curve_key=None):
    """Make sock a CURVE client of the daemon described by `info` (the
    connection file) when the daemon announces a server key. curve_key is a
    .key file path or a (public, secret) pair of Z85 strings; by default the
    client key pair that a loopback daemon writes into its 0600 connection
    file (curve_client_public_key, curve_client_secret_key), else
    $GEARSIM_CURVE_KEY. Without a server key in info nothing is done."""
    server = info.get("curve_server_key")
    if not server:
        return False
    if not curve_key and info.get("curve_client_secret_key"):
        # the daemon's own client pair: always the right key for this daemon
        curve_key = (info.get("curve_client_public_key", ""), info["curve_client_secret_key"])
    curve_key = curve_key or os.environ.get("GEARSIM_CURVE_KEY")
    if not curve_key:
        raise GearsimError("invalid_argument",
                           "the daemon requires CURVE: give a client key (Client(curve_key=...), "
                           "gearctl --curve-key FILE or GEARSIM_CURVE_KEY) made by `gearctl keys`")
    if isinstance(curve_key, (tuple, list)):
        public, secret = (k.encode() if isinstance(k, str) else k for k in curve_key)
    else:
        public, secret = read_key_file(curve_key)
    import zmq
    sock.setsockopt(zmq.CURVE_SERVERKEY, server.encode())
    sock.setsockopt(zmq.CURVE_PUBLICKEY, public)
    sock.setsockopt(zmq.CURVE_SECRETKEY, secret)
    return True
