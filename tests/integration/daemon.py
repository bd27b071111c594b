# SPDX-License-Identifier: MIT
"""Start a real gearsimd under mpirun for an integration test, and always tear it down.

    with Daemon(ranks=2) as d:          # temp dir with conn.json and the data dir
        c = d.client()                  # a gearsim.Client on that connection file
        ...

Teardown: `shutdown` command, then SIGTERM to the process group we started,
then SIGKILL, each with a timeout; an atexit hook covers crashes of the test.
GEARSIM_FAKE_DAEMON=1 runs tests/integration/fakedaemon.py instead (for
testing the clients themselves, never to judge the daemon)."""
import atexit
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_ROOT = os.environ.get("GEARSIM_SOURCE_ROOT") or os.path.abspath(os.path.join(HERE, "..", ".."))
BUILD_ROOT = os.environ.get("GEARSIM_BUILD_ROOT") or os.path.join(SOURCE_ROOT, "build")
sys.path.insert(0, os.path.join(SOURCE_ROOT, "clients", "python"))

import gearsim  # noqa: E402

MPI_ENV = {
    "OMPI_ALLOW_RUN_AS_ROOT": "1",
    "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
    "OMPI_MCA_rmaps_base_oversubscribe": "1",
    "OMPI_MCA_btl_vader_single_copy_mechanism": "none",
    "HDF5_USE_FILE_LOCKING": "FALSE",
    "OPENBLAS_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    # Open MPI on loopback only (deploy/env.sh, docs/RELIABILITY.md): shared
    # memory between ranks, runtime advertised on lo, and the wildcard
    # listeners of mpirun turned into loopback ones by the preloaded shim.
    "OMPI_MCA_btl": "self,vader",
    "OMPI_MCA_oob_tcp_if_include": "lo",
    "OMPI_MCA_btl_tcp_if_include": "lo",
}


def loopback_preload():
    """The shim that binds mpirun's wildcard listeners to loopback."""
    return os.path.join(BUILD_ROOT, "src", "daemon", "gearsim-loopback.so")
FAKE = os.environ.get("GEARSIM_FAKE_DAEMON") == "1"
_live = []


def gearsimd_path():
    return os.path.join(BUILD_ROOT, "src", "daemon", "gearsimd")


def scene_path(name):
    """deploy/scenes/<name>.json of the checkout."""
    return os.path.join(SOURCE_ROOT, "deploy", "scenes", name + ".json")


def load_scene(name):
    with open(scene_path(name)) as f:
        return json.load(f)


class DaemonError(RuntimeError):
    pass


class Daemon:
    """One gearsimd run in its own temporary directory (also its data dir)."""

    def __init__(self, ranks=1, extra_args=(), startup_timeout=60.0, keep=None, curve_key=None,
                 data_dir=None, resume=False, fsize=None):
        """data_dir: use (and keep) this directory instead of a new temporary
        one, e.g. to restart on the data of a killed daemon; resume: pass
        --resume; fsize: RLIMIT_FSIZE (bytes) set on the gearsimd ranks once
        they answer (limit_file_size)."""
        self.given_dir = data_dir
        self.fsize = fsize
        if resume:
            extra_args = list(extra_args) + ["--resume"]
        self.ranks = ranks
        self.curve_key = curve_key   # client key used by start/stop/client() when the daemon runs CURVE
        self.extra_args = list(extra_args)
        self.startup_timeout = startup_timeout
        self.keep = os.environ.get("GEARSIM_KEEP_TMP") == "1" if keep is None else keep
        self.proc = None
        self.dir = None
        self.hello = None
        self.returncode = None

    # ---------------------------------------------------------------- start
    def command(self):
        if FAKE:
            return [sys.executable, os.path.join(HERE, "fakedaemon.py"),
                    "--connection-file", self.conn_file, "--data-dir", self.dir] + self.extra_args
        return ["mpirun", "-n", str(self.ranks), gearsimd_path(),
                "--connection-file", self.conn_file, "--data-dir", self.dir] + self.extra_args

    def start(self):
        if not FAKE and not os.access(gearsimd_path(), os.X_OK):
            raise DaemonError(f"{gearsimd_path()} is not built")
        if self.given_dir:
            self.dir = self.given_dir
            os.makedirs(self.dir, exist_ok=True)
        else:
            self.dir = tempfile.mkdtemp(prefix="gearsim-it-")
        self.conn_file = os.path.join(self.dir, "conn.json")
        if self.given_dir and os.path.exists(self.conn_file):
            os.unlink(self.conn_file)   # left by a killed run
        env = dict(os.environ, **MPI_ENV)
        if not FAKE and os.path.exists(loopback_preload()):
            env["LD_PRELOAD"] = loopback_preload()
        mode = "ab" if self.given_dir else "wb"
        self._out = open(os.path.join(self.dir, "daemon.out"), mode)
        self._err = open(os.path.join(self.dir, "daemon.err"), mode)
        self.proc = subprocess.Popen(self.command(), cwd=self.dir, env=env, stdin=subprocess.DEVNULL,
                                     stdout=self._out, stderr=self._err, start_new_session=True)
        _live.append(self)
        deadline = time.monotonic() + self.startup_timeout
        while not os.path.exists(self.conn_file):
            if self.proc.poll() is not None:
                raise DaemonError(f"gearsimd exited with {self.proc.returncode} before writing "
                                  f"its connection file:\n{self.log_tail()}")
            if time.monotonic() > deadline:
                raise DaemonError(f"no connection file after {self.startup_timeout:g} s:\n{self.log_tail()}")
            time.sleep(0.05)
        last = None
        while True:
            try:
                with gearsim.Client(self.conn_file, timeout=2.0, retries=0, curve_key=self.curve_key) as c:
                    self.hello = c.hello()
                break
            except gearsim.GearsimError as e:   # half-written file, or not answering yet
                last = e
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise DaemonError(f"gearsimd does not answer hello ({last}):\n{self.log_tail()}")
            time.sleep(0.1)
        with open(self.conn_file) as f:
            self.connection = json.load(f)
        if self.fsize is not None:
            self.limit_file_size(self.fsize)
        return self

    def limit_file_size(self, nbytes):
        """RLIMIT_FSIZE on the running gearsimd ranks only (mpirun and PMIx
        need to write more than that); returns the pids limited."""
        import resource
        done = []
        for p in self.session_pids():
            try:
                with open(f"/proc/{p}/comm") as f:
                    if f.read().strip() != "gearsimd":
                        continue
                resource.prlimit(p, resource.RLIMIT_FSIZE, (int(nbytes), int(nbytes)))
                done.append(p)
            except (OSError, ValueError):
                pass
        if not done:
            raise DaemonError("no gearsimd process to limit")
        return done

    def client(self, **kw):
        if self.curve_key is not None:
            kw.setdefault("curve_key", self.curve_key)
        return gearsim.Client(self.conn_file, **kw)

    def path(self, rel):
        """Absolute path of a file in the daemon's data directory."""
        return os.path.join(self.dir, rel)

    def alive(self):
        return self.proc is not None and self.proc.poll() is None

    def log_tail(self, n=4000):
        out = []
        for name in ("daemon.out", "daemon.err"):
            try:
                with open(os.path.join(self.dir, name), "rb") as f:
                    data = f.read()[-n:].decode(errors="replace")
                out.append(f"--- {name} ---\n{data}")
            except OSError:
                pass
        return "\n".join(out)

    # ---------------------------------------------------------------- stop
    def session_pids(self):
        """Every process of the session we started (mpirun is its leader).
        Open MPI puts each rank in a process group of its own, so the group
        of mpirun does not reach the ranks; the session does."""
        sid, pids = self.proc.pid, []
        for name in os.listdir("/proc"):
            if not name.isdigit():
                continue
            try:
                with open(f"/proc/{name}/stat") as f:
                    stat = f.read()
            except OSError:
                continue
            fields = stat[stat.rindex(")") + 2:].split()
            if len(fields) > 3 and int(fields[3]) == sid:
                pids.append(int(name))
        return pids

    def gearsimd_pids(self):
        """The gearsimd processes of the session (its ranks), rank 0 (the
        pid of the connection file) first when it is among them."""
        out = []
        for p in self.session_pids():
            try:
                with open(f"/proc/{p}/comm") as f:
                    if f.read().strip() == "gearsimd":
                        out.append(p)
            except OSError:
                pass
        try:
            with open(self.conn_file) as f:
                r0 = json.load(f).get("pid")
        except (OSError, ValueError):
            r0 = None
        return sorted(out, key=lambda p: p != r0)

    def kill(self):
        """SIGKILL every process of the daemon (mpirun and all ranks) at once,
        as a crash of the machine would; keep the data directory. Returns the
        exit status of mpirun."""
        pids = self.session_pids()
        for p in pids:
            try:
                os.kill(p, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.proc.wait(timeout=30)
        deadline = time.monotonic() + 10
        while self.session_pids() and time.monotonic() < deadline:
            time.sleep(0.02)
        return self._ended()

    def _ended(self):
        """Book the exit of mpirun (already waited for); returns its status."""
        self.returncode = self.proc.returncode
        self.proc = None
        for f in (self._out, self._err):
            f.close()
        if self in _live:
            _live.remove(self)
        return self.returncode

    def _signal(self, sig):
        try:
            os.killpg(self.proc.pid, sig)   # the group we created with start_new_session
        except ProcessLookupError:
            pass

    def stop(self, graceful=True):
        """Shutdown command, then SIGTERM, then SIGKILL. Returns how it ended:
        'shutdown', 'sigterm', 'sigkill' or 'exited' (already gone)."""
        if self.proc is None:
            return "exited"
        how = "exited"
        if self.proc.poll() is None and graceful:
            try:
                with gearsim.Client(self.conn_file, timeout=5.0, retries=0, curve_key=self.curve_key) as c:
                    c.shutdown()
                self.proc.wait(timeout=20)
                how = "shutdown"
            except (gearsim.GearsimError, subprocess.TimeoutExpired):
                pass
        if self.proc.poll() is None:
            self._signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=10)
                how = "sigterm"
            except subprocess.TimeoutExpired:
                pass
        if self.proc.poll() is None:
            self._signal(signal.SIGKILL)
            self.proc.wait(timeout=10)
            how = "sigkill"
        # ranks that outlived mpirun would still be in our process group
        self._signal(signal.SIGKILL)
        self._ended()
        if self.dir and not self.keep and not self.given_dir:
            shutil.rmtree(self.dir, ignore_errors=True)
        return how

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


@atexit.register
def _teardown_all():
    for d in list(_live):
        try:
            d.stop(graceful=False)
        except Exception:   # noqa: BLE001 - best effort at exit
            pass
