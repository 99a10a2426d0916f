"""The simulation thread outlives any fault, even a reset that raises."""

from __future__ import annotations

from helpers import wait_for

from dcmviz.config import Config
from dcmviz.dashboard.loop import SimLoop
from dcmviz.session import Session


def test_a_reset_that_raises_rebuilds_the_session() -> None:
    config = Config().replace(sim={"backend": "lip"})
    events: list[tuple[str, str]] = []
    loop = SimLoop(
        lambda c: Session(c, backend="lip"), config, on_event=lambda k, m: events.append((k, m))
    )
    broken = loop.session

    def fail() -> None:
        raise RuntimeError("step failed")

    def fail_reset() -> None:
        raise RuntimeError("reset failed too")

    broken.step, broken.reset = fail, fail_reset
    loop.start()
    try:
        assert wait_for(lambda: loop.session is not broken)
        assert wait_for(lambda: loop.session.t > 0.5)  # the new session walks
        assert loop._thread.is_alive()
        assert any("restarts" in m for _, m in events)
    finally:
        loop.stop()
