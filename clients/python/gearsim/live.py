# SPDX-License-Identifier: MIT
"""A live terminal display of a run, driven by telemetry and progress events.

On a terminal it redraws a block of lines in place (ANSI cursor movement) at
most ten times a second: progress bar, simulated time, steps/s, rpm of each
body and the energy account. When the stream is not a terminal (a pipe, a
log file) it prints one line each time the run crosses another 10%.

The rate shown is the current one: steps per wall second over the events of
the last `rate_window` seconds (telemetry and progress both carry the step),
the daemon's own figure only until two events have come."""
import collections
import shutil
import sys
import time

ENERGY_KEYS = (("kinetic", "kinetic"), ("potential", "potential"), ("total", "total"),
               ("work_in", "work in"), ("dissipated", "dissipated"), ("balance_residual", "residual"))


def _fmt_e(x):
    return "      -" if x is None else f"{x: .4e}"


class LiveDisplay:
    """Feed it events: on_telemetry(ev), on_progress(ev); call close() at the end.

    target_time -- simulated time at which the run ends (for the fraction
                   when no progress event has arrived yet)
    start_time  -- simulated time at which it starts
    rate_window -- wall seconds over which the current rate is measured
    clock       -- the wall clock (time.monotonic)
    """

    def __init__(self, stream=None, title="", target_time=None, start_time=0.0, tty=None,
                 min_interval=0.1, rate_window=1.0, clock=time.monotonic):
        self.stream = stream or sys.stdout
        self.tty = self.stream.isatty() if tty is None else tty
        self.title = title
        self.target_time = target_time
        self.start_time = start_time
        self.min_interval = min_interval
        self.fraction = 0.0
        self.time = start_time
        self.step = 0
        self.steps_per_second = None
        self.bodies = []
        self.energy = {}
        self.telemetry_count = 0
        self._lines = 0
        self._last_draw = 0.0
        self._decile = -1
        self.rate_window = rate_window
        self._clock = clock
        self._samples = collections.deque()   # (wall, step) of recent events

    # ---------------------------------------------------------------- events
    def on_telemetry(self, ev):
        self.telemetry_count += 1
        self.time = ev.get("time", self.time)
        self.step = ev.get("step", self.step)
        self._sample()
        self.bodies = ev.get("bodies", self.bodies) or []
        self.energy = ev.get("energy", self.energy) or {}
        if self.target_time and self.target_time > self.start_time:
            f = (self.time - self.start_time) / (self.target_time - self.start_time)
            self.fraction = max(self.fraction, min(max(f, 0.0), 1.0))
        self.update()

    def on_progress(self, ev):
        self.fraction = max(self.fraction, float(ev.get("fraction", self.fraction)))
        self.time = ev.get("time", self.time)
        if ev.get("step") is not None:
            self.step = ev["step"]
            self._sample()
        if ev.get("steps_per_second") is not None:
            self.steps_per_second = float(ev["steps_per_second"])
        self.update()

    def _sample(self):
        """Remember (now, step); keep the last rate_window seconds (at least two)."""
        now = self._clock()
        self._samples.append((now, self.step))
        while len(self._samples) > 2 and now - self._samples[1][0] >= self.rate_window:
            self._samples.popleft()

    def on_event(self, ev):
        t = ev.get("type")
        if t == "telemetry":
            self.on_telemetry(ev)
        elif t == "progress":
            self.on_progress(ev)

    # ---------------------------------------------------------------- output
    def sps(self):
        """Steps per wall second now: over the recent events, else the
        daemon's last figure (None before either)."""
        if len(self._samples) >= 2:
            (t0, s0), (t1, s1) = self._samples[0], self._samples[-1]
            if t1 - t0 > 0.02 and s1 > s0:   # two of the daemon's chunks (about 10 ms each)
                return (s1 - s0) / (t1 - t0)
        return self.steps_per_second

    def lines(self):
        width = max(shutil.get_terminal_size((80, 24)).columns, 40)
        barw = max(min(width - 40, 50), 10)
        filled = int(round(self.fraction * barw))
        sps = self.sps()
        sps_s = f"{sps:,.0f} steps/s" if sps else "- steps/s"
        tgt = f" / {self.target_time:.6g}" if self.target_time else ""
        out = []
        if self.title:
            out.append(f"gearsim  {self.title}"[:width])
        out.append(f"[{'#' * filled}{'-' * (barw - filled)}] {100 * self.fraction:5.1f}%")
        out.append(f"t = {self.time:.6f}{tgt} s   step {self.step}   {sps_s}"[:width])
        for b in self.bodies:
            out.append(f"  {str(b.get('name', '?')):<14} {b.get('rpm', 0.0):>12.2f} rpm"[:width])
        e = self.energy
        if e:
            out.append("  energy (J)  " + "  ".join(f"{lbl} {_fmt_e(e.get(k))}" for k, lbl in ENERGY_KEYS[:3]))
            out.append("              " + "  ".join(f"{lbl} {_fmt_e(e.get(k))}" for k, lbl in ENERGY_KEYS[3:]))
        return out

    def summary_line(self):
        sps = self.sps()
        parts = [f"{100 * self.fraction:5.1f}%", f"t={self.time:.6g} s", f"step {self.step}"]
        if sps:
            parts.append(f"{sps:,.0f} steps/s")
        if self.bodies:
            parts.append("rpm " + " ".join(f"{b.get('name')}={b.get('rpm', 0.0):.1f}" for b in self.bodies))
        e = self.energy
        if e:
            parts.append(f"E={e.get('total', 0.0):.6g} J in={e.get('work_in', 0.0):.6g} "
                         f"diss={e.get('dissipated', 0.0):.6g} resid={e.get('balance_residual', 0.0):.3g}")
        return "  ".join(parts)

    def update(self, force=False):
        if self.tty:
            now = time.monotonic()
            if not force and now - self._last_draw < self.min_interval:
                return
            self._last_draw = now
            self._draw()
        else:
            decile = int(self.fraction * 10 + 1e-9)
            if decile > self._decile:
                self._decile = decile
                self.stream.write(self.summary_line() + "\n")
                self.stream.flush()

    def _draw(self):
        lines = self.lines()
        buf = []
        if self._lines:
            buf.append(f"\x1b[{self._lines}F")   # back to the first line of the block
        buf.append("\x1b[J")                     # clear it and everything below
        buf.append("\n".join(lines) + "\n")
        self.stream.write("".join(buf))
        self.stream.flush()
        self._lines = len(lines)

    def close(self, done=None):
        """Final redraw (100% when the run completed)."""
        if done is not None and not done.get("cancelled") and not done.get("error"):
            self.fraction = 1.0
            self.time = done.get("time", self.time)
            self.step = done.get("step", self.step)
            wall = done.get("wall_seconds")
            if wall and done.get("steps"):   # the final line: the whole run's mean rate
                self.steps_per_second = done["steps"] / wall
                self._samples.clear()
        if self.tty:
            self._draw()
        elif int(self.fraction * 10 + 1e-9) > self._decile or (done is not None and self._decile < 10):
            self._decile = 10
            self.stream.write(self.summary_line() + "\n")
            self.stream.flush()
