#!/usr/bin/python3
# SPDX-License-Identifier: MIT
"""gearsim.live.LiveDisplay shows the current rate: events from a run whose
speed changes (1000 steps/s for 3 s, then 5000 steps/s) on a stand-in clock,
with a daemon figure that never changes after the first progress event; the
rate printed follows the run (1000, then 5000 within the window), not the
first figure. The non-terminal form prints one line per 10 %, the terminal
form redraws its block, and close() reports the whole run's mean rate."""
import io
import re
import unittest

from gearsim.live import LiveDisplay


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def rates(text):
    return [float(m.replace(",", "")) for m in re.findall(r"([\d,]+) steps/s", text)]


def drive(live, clock, phases, dt=0.05):
    """Telemetry every dt wall seconds; progress events with a stale rate."""
    step, t = 0, 0.0
    total = sum(r * d for r, d in phases)
    live.on_progress({"fraction": 0.0, "step": 0, "steps_per_second": 17.0})
    for rate, dur in phases:
        for _ in range(int(round(dur / dt))):
            clock.t += dt
            step += int(rate * dt)
            t = step * 1e-4
            live.on_telemetry({"step": step, "time": t, "bodies": [{"name": "a", "rpm": 1.0}],
                               "energy": {"total": 1.0}})
            live.on_progress({"fraction": step / total, "step": step, "steps_per_second": 17.0})
    return step


class Rate(unittest.TestCase):
    def test_current_rate_not_first(self):
        clock, out = Clock(), io.StringIO()
        live = LiveDisplay(stream=out, tty=False, target_time=1.3, clock=clock)
        self.assertIsNone(live.sps())
        live.on_progress({"fraction": 0.0, "step": 0, "steps_per_second": 17.0})
        self.assertEqual(live.sps(), 17.0)   # the daemon's figure before any measured interval
        steps = drive(live, clock, [(1000.0, 3.0), (5000.0, 2.0)])
        self.assertEqual(steps, 13000)
        self.assertAlmostEqual(live.sps(), 5000.0, delta=1.0)
        lines = out.getvalue().splitlines()
        self.assertEqual(len(lines), 11)     # 0 %, 10 %, ..., 100 %
        r = rates(out.getvalue())
        slow = [x for x in r[1:] if abs(x - 1000.0) < 1.0]
        fast = [x for x in r[1:] if abs(x - 5000.0) < 1.0]
        self.assertGreaterEqual(len(slow), 1, r)
        self.assertGreaterEqual(len(fast), 2, r)
        self.assertNotIn(17.0, r[1:], "the first progress event's rate stayed on the line")
        live.close({"steps": 13000, "wall_seconds": 5.0, "time": 1.3, "step": 13000})
        self.assertEqual(live.sps(), 13000 / 5.0)

    def test_window(self):
        clock = Clock()
        live = LiveDisplay(stream=io.StringIO(), tty=False, clock=clock, rate_window=1.0)
        drive(live, clock, [(2000.0, 2.0), (4000.0, 0.5)])
        # the shortest span of events reaching back rate_window: 1.05 s (events
        # every 0.05 s), 0.55 s of it at 2000 and 0.5 s at 4000 steps/s
        self.assertAlmostEqual(live.sps(), (2000.0 * 0.55 + 4000.0 * 0.5) / 1.05, delta=1e-6)

    def test_tty_redraw(self):
        clock, out = Clock(), io.StringIO()
        live = LiveDisplay(stream=out, tty=True, title="pair", target_time=1.3, clock=clock, min_interval=0.0)
        drive(live, clock, [(1000.0, 1.0), (5000.0, 1.5)])
        text = out.getvalue()
        self.assertIn("\x1b[", text)                     # redrawn in place
        last = text.rsplit("\x1b[J", 1)[1]
        self.assertIn("gearsim  pair", last)
        self.assertEqual(rates(last), [5000.0])


if __name__ == "__main__":
    unittest.main()
