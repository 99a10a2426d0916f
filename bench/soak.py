"""An hour of use, shortened: a continuous-mode walk with a tab connected and a push every few
seconds, presets switched and recordings toggled along the way (numbers printed, not asserted).

    PYTHONPATH=. python3 bench/soak.py [--minutes 30] [--tab ws|chromium] [--sample-s 30]
                                       [--push-every 4] [--switch-every 180] [--heap fixed|glibc]

Every ``--sample-s`` seconds it prints the wall minute, what runs, steps walked since the reset,
the process RSS (MB), the cost per control tick (CPU µs of the simulation thread per tick over
the window, which load from other processes does not inflate; and the loop's wall-clock mean of
its last ticks) and the real-time factor over the window.  At the end: the RSS slope (MB/min, least squares over the
samples after the first round of presets) and the cost trend (µs/min and the last quarter's median
over the first's) of the continuous walk's samples.  Flat memory and constant cost mean nothing
grows with the steps walked.

The slopes are fitted after every preset has run once (each robot's models load once per
process: a step up in RSS, not a leak).  Every ``--switch-every`` seconds another preset runs
for 20 s (then the continuous walk comes
back, restarted) and a recording runs for 15 s and is stopped (its .rrd handed back and freed).
"""

from __future__ import annotations

import argparse
import os
import resource
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import viser  # noqa: E402

from dcmviz.config import config_from_dict, load_preset  # noqa: E402
from dcmviz.dashboard import Dashboard  # noqa: E402
from dcmviz.dashboard.heap import fix_mmap_threshold  # noqa: E402

OTHER_PRESETS = ("lateral_push", "g1_walk", "stairs")
OTHER_RUN_S = 20.0
RECORD_S = 15.0


def rss_mb() -> float:
    """Resident set size of this process now (MB)."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 1e6


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class SimClock:
    """Sim seconds and control ticks advanced (across resets, which send both back), polled
    often, and the CPU time of the simulation thread (its clock, not the wall's: other
    processes on the machine do not inflate it)."""

    def __init__(self, dashboard: Dashboard) -> None:
        self.loop = dashboard.loop
        self.t_last = self.loop.session.t
        self.ticks_last = self.loop.session.metrics.ticks
        self.sim = 0.0
        self.ticks = 0
        self._cpu_clock = time.pthread_getcpuclockid(self.loop._thread.ident)  # the sim thread

    def poll(self) -> None:
        session = self.loop.session
        t, ticks = session.t, session.metrics.ticks
        self.sim += t - self.t_last if t >= self.t_last else t
        self.ticks += ticks - self.ticks_last if ticks >= self.ticks_last else ticks
        self.t_last, self.ticks_last = t, ticks

    def cpu_s(self) -> float:
        return time.clock_gettime(self._cpu_clock)


def fit_slope(x: np.ndarray, y: np.ndarray) -> float:
    return float(np.polyfit(x, y, 1)[0]) if len(x) >= 2 else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--preset", default=str(ROOT / "presets" / "walk_forward.toml"))
    parser.add_argument("--tab", choices=("ws", "chromium"), default="ws")
    parser.add_argument("--sample-s", type=float, default=30.0)
    parser.add_argument("--push-every", type=float, default=4.0, help="s between pushes")
    parser.add_argument("--switch-every", type=float, default=180.0,
                        help="s between preset switches and recordings")  # fmt: skip
    parser.add_argument("--heap", choices=("fixed", "glibc"), default="fixed",
                        help="fixed: the mmap threshold held as serve() and app.py hold it; "
                        "glibc: its dynamic default (the heap grew at robot switches)")  # fmt: skip
    args = parser.parse_args()

    data = load_preset(args.preset).to_dict()
    data["name"], data["pushes"] = "Soak: continuous walk", []
    data["gait"]["mode"] = "continuous"
    walk = config_from_dict(data)
    heap = "mmap threshold fixed" if args.heap == "fixed" and fix_mmap_threshold() else "glibc"
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    dashboard = Dashboard(server, walk, presets_dir=ROOT / "presets")
    port = server.get_port()
    total_s = 60.0 * args.minutes
    tab, browser_ctx = open_tab(args.tab, port, total_s)
    time.sleep(1.0)  # the threads are running
    loop, clock = dashboard.loop, SimClock(dashboard)
    print(f"soak: {args.minutes:g} min, continuous {walk.robot.model} on {walk.sim.backend}, "
          f"one {args.tab} tab, a push every {args.push_every:g} s, a preset switch and a "
          f"recording every {args.switch_every:g} s; heap: {heap}; "
          f"load average {os.getloadavg()[0]:.2f}")  # fmt: skip
    print(" min  running        steps  RSS MB  CPU µs/tick  wall µs/tick   RTF  records  notes")
    # min, rss, µs, rtf, main walk, its time buffer full
    samples: list[tuple[float, float, float, float, bool, bool]] = []
    t0 = time.perf_counter()
    next_push, next_sample = t0 + 2.0, t0 + args.sample_s
    next_switch = t0 + args.switch_every / 2
    other_until = record_until = None
    running, sign, k_other = "continuous", 1.0, 0
    window_sim, window_wall, window_ticks, window_cpu = 0.0, t0, 0, clock.cpu_s()
    while (now := time.perf_counter()) - t0 < total_s:
        time.sleep(0.05)
        clock.poll()
        if now >= next_push:
            sign = -sign
            body = "torso"
            loop.post("push", {"force": (0.0, 40.0 * sign, 0.0), "duration": 0.2, "ramp": 0.0,
                               "body": body})  # fmt: skip
            next_push = now + args.push_every
        if now >= next_switch and other_until is None:
            name = OTHER_PRESETS[k_other % len(OTHER_PRESETS)]
            k_other += 1
            dashboard.preset_panel.on_preset_selected(name)
            running, other_until = name, now + OTHER_RUN_S
            dashboard.recording.on_record(True, None)
            record_until = now + RECORD_S
            next_switch = now + args.switch_every
        if record_until is not None and now >= record_until:
            data = dashboard.recording.on_record(False, None)
            print(f"      (recording stopped: {0 if data is None else len(data) / 1e6:.1f} MB)")
            record_until = None
        if other_until is not None and now >= other_until:
            dashboard.editor.apply_config(walk, None)
            running, other_until = "continuous", None
        if now >= next_sample:
            minute = (now - t0) / 60.0
            wall = now - window_wall
            rtf = (clock.sim - window_sim) / wall
            cpu = clock.cpu_s()
            # CPU µs of the simulation thread per control tick (stepping, publishing snapshots)
            cost_us = 1e6 * (cpu - window_cpu) / max(clock.ticks - window_ticks, 1)
            wall_us = 1e6 * loop.snapshot.status.step_time_s
            rss = rss_mb()
            records = len(loop.session.realised_steps())
            main_walk = running == "continuous" and other_until is None
            timeline = loop.timeline  # full: its columns hold BUFFER_S of this walk's robot
            full = timeline.seconds_kept() >= timeline.seconds - 0.5
            samples.append((minute, rss, cost_us, rtf, main_walk, full))
            print(f"{minute:4.1f}  {running:<13} {loop.session.steps_completed:5d}  {rss:6.1f}  "
                  f"{cost_us:7.0f}  {wall_us:8.0f}  {rtf:4.2f}  {records:7d}  falls {loop.falls}, "
                  f"notifications {len(dashboard.notifications)}, "
                  f"render {dashboard.view.fps:4.1f} fps")  # fmt: skip
            window_sim, window_wall, window_ticks, window_cpu = clock.sim, now, clock.ticks, cpu
            next_sample = now + args.sample_s
    first_cycle_min = (args.switch_every / 2 + args.switch_every * (len(OTHER_PRESETS) - 1)
                       + OTHER_RUN_S + args.sample_s) / 60.0  # fmt: skip
    if first_cycle_min >= args.minutes - 1.0:  # no full round of presets in this run
        first_cycle_min = 2.0
    summarise(samples, max(2.0, first_cycle_min))
    timeline = loop.timeline
    print(f"time buffer {timeline.nbytes / 1e6:.1f} MB holding {timeline.seconds_kept():.0f} s "
          f"of {timeline.seconds:.0f} s")  # fmt: skip
    print(
        f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3:.0f} MB; "
        f"load average {os.getloadavg()[0]:.2f}"
    )
    close_tab(tab, browser_ctx)
    dashboard.stop()
    server.stop()


def summarise(
    samples: list[tuple[float, float, float, float, bool, bool]], after_min: float
) -> None:
    """RSS slope after ``after_min`` (every preset loaded once: each robot's models are built
    once per process, a step up, not a leak), and within each uninterrupted stretch of the
    continuous walk once its time buffer is full (what grows with the steps walked: a buffer
    filling after a robot switch is bounded by its size, printed), and the slope of the RSS at
    the stretches' ends, the buffer full (what grows with the rounds of presets); the cost
    trend of the continuous walk."""
    a = np.array([s[:4] for s in samples]) if samples else np.zeros((0, 4))
    main = np.array([s[4] for s in samples], bool)
    full = np.array([s[5] for s in samples], bool)
    late = a[:, 0] >= after_min
    overall = fit_slope(a[late, 0], a[late, 1]) if late.sum() >= 3 else float("nan")
    stretches, start = [], None  # runs of continuous-walk samples, the first after a switch out
    for i in range(len(a) + 1):
        if i < len(a) and main[i] and full[i]:
            start = i if start is None else start
            continue
        if start is not None and i - start >= 3:
            stretches.append(slice(start, i))
        start = None
    ends = [s.stop - 1 for s in stretches if a[s.stop - 1, 0] >= after_min]
    floors = fit_slope(a[ends, 0], a[ends, 1]) if len(ends) >= 3 else float("nan")
    within = [(fit_slope(a[s, 0], a[s, 1]), a[s, 0][-1] - a[s, 0][0]) for s in stretches]
    weights = np.array([w for _, w in within])
    within_slope = float(np.average([v for v, _ in within], weights=weights)) if within else 0.0
    walk = a[main & (a[:, 0] >= 1.0)]
    cost_slope = fit_slope(walk[:, 0], walk[:, 2]) if len(walk) else float("nan")
    q = max(1, len(walk) // 4)
    ratio = float(np.median(walk[-q:, 2]) / np.median(walk[:q, 2])) if len(walk) else float("nan")
    print(
        f"RSS slope within the continuous walk's stretches, buffer full, {within_slope:+.2f} "
        f"MB/min ({len(within)} stretches, {weights.sum() if within else 0:.1f} min); of their "
        f"ends after minute {after_min:.1f} {floors:+.2f} MB/min "
        f"({', '.join(f'{a[i, 1]:.0f}' for i in ends)} MB); over everything "
        f"after minute {after_min:.1f} {overall:+.2f} MB/min; RSS {a[:, 1].min():.0f}–"
        f"{a[:, 1].max():.0f} MB.  CPU per tick of the continuous walk {cost_slope:+.2f} µs/min, "
        f"last quarter / first quarter {ratio:.3f}; real-time factor median "
        f"{np.median(a[:, 3]):.2f} (min {a[:, 3].min():.2f})"
    )


def open_tab(kind: str, port: int, total_s: float):
    """A websocket client (another process) or one headless Chromium page, kept open."""
    if kind == "ws":
        cmd = [sys.executable, str(ROOT / "bench" / "wsclients.py"), str(port), "1",
               str(total_s + 30), "--warmup", "1"]  # fmt: skip
        return subprocess.Popen(cmd, stdout=subprocess.DEVNULL), None
    from playwright.sync_api import sync_playwright

    from dcmviz.dashboard.headless import launch_chromium

    ctx = sync_playwright().start()
    browser = launch_chromium(ctx)
    page = browser.new_page(viewport={"width": 1280, "height": 720})
    page.goto(f"http://127.0.0.1:{port}")
    return browser, ctx


def close_tab(tab, ctx) -> None:
    if ctx is None:
        tab.terminate()
        tab.wait(timeout=10)
        return
    tab.close()
    ctx.stop()


if __name__ == "__main__":
    main()
