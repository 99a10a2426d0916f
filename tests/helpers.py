"""Small helpers shared by the tests: a free loopback port, waiting on a condition, a child
process's output lines, an RK4 integration, bench/robustness.py as a module."""

from __future__ import annotations

import importlib.util
import socket
import sys
import threading
import time
from collections.abc import Callable
from functools import cache
from pathlib import Path


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(condition: Callable[[], object], timeout: float = 20.0, dt: float = 0.02) -> bool:
    """Poll ``condition`` until it holds (True) or ``timeout`` s have passed (its last value).

    20 s: a passing wait returns as soon as its condition holds, so the bound only decides when
    a two-core machine loaded by the rest of the suite is called too slow (10 s before; the
    guard tests' own copy already waited 20 s)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(dt)
    return bool(condition())


def rk4(f: Callable, y, h: float, n: int):
    """``n`` classical Runge-Kutta steps of ``h`` of y' = f(y) from ``y`` (the tests' independent
    integration of the LIP with its CoP on a sole edge)."""
    for _ in range(n):
        k1 = f(y)
        k2 = f(y + h / 2 * k1)
        k3 = f(y + h / 2 * k2)
        k4 = f(y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y


class OutputLines:
    """The lines a child process prints, read by a thread, so a test waits with a timeout
    instead of blocking in ``readline`` on a child that prints nothing."""

    def __init__(self, stream) -> None:
        self.lines: list[str] = []
        self._changed = threading.Condition()
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream) -> None:
        for line in stream:
            with self._changed:
                self.lines.append(line)
                self._changed.notify_all()

    def wait_for(self, condition: Callable[[list[str]], bool], timeout: float) -> list[str]:
        """The lines so far once ``condition(lines)`` holds or ``timeout`` s have passed."""
        with self._changed:
            self._changed.wait_for(lambda: condition(self.lines), timeout)
            return list(self.lines)


@cache
def robustness_bench():
    """bench/robustness.py as a module: the scenarios the bench runs, built the same way."""
    path = Path(__file__).resolve().parents[1] / "bench" / "robustness.py"
    spec = importlib.util.spec_from_file_location("robustness", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # (its dataclasses look their module up)
    spec.loader.exec_module(module)
    return module


def locked_arms_g1(tmp_path: Path) -> str:
    """The built-in G1's robot file without its ``[joints] keep``, written to ``tmp_path``: the
    G1 as shipped before its arms were actuated (waist and arms locked in its posture)."""
    from dcmviz.robots.file import builtin_path

    text = builtin_path("g1").read_text(encoding="utf-8")
    start, end = text.index("[joints]"), text.index("[feet.left]")
    path = tmp_path / "g1_locked_arms.toml"
    path.write_text(text[:start] + text[end:], encoding="utf-8")
    return str(path)


def survives_pull(
    robot: str, level_pct: float, side: float, recovery: str = "next_step", watch=None
) -> bool:
    """True if ``robot`` survives bench/robustness.py's tug of war: a torso pull ramped over 6 s
    to ``level_pct`` % of its weight towards ``side`` (±1: ±y) and held while it walks 12 steps;
    ``watch(session, tick)`` runs after every tick (:meth:`Session.subscribe`)."""
    from dcmviz.robots import load_robot
    from dcmviz.session import Session

    rb = robustness_bench()
    base = rb.walking_config(robot, overrides=[f'control.recovery="{recovery}"'])
    config = rb.pull_config(base, load_robot(robot).spec.mass_kg, level_pct, side)
    session = Session(config, backend="mujoco")
    if watch is not None:
        session.subscribe(lambda tick: watch(session, tick))
    return not session.run(rb.PULL_DURATION_S, stop_on_fall=True).fell
