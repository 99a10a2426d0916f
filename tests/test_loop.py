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
        assert loop.running()
        assert any("restarts" in m for _, m in events)
    finally:
        loop.stop()


def test_realised_footsteps_are_rebuilt_only_when_a_foot_lands() -> None:
    """A tick's realised footsteps (up to session.REALISED_IN_TICK; a cost per tick that grew
    with the steps walked before) are the same tuple from one publish to the next until a foot
    lands, and then equal the session's records."""
    import numpy as np

    config = Config().replace(sim={"backend": "lip"}, gait={"mode": "continuous"})
    loop = SimLoop(lambda c: Session(c, backend="lip"), config)  # driven by hand, no thread
    session = loop.session
    rebuilt, last, landed = 0, None, 0
    while session.steps_completed < 6:
        before = session.steps_completed
        session.step()
        landed += session.steps_completed - before
        loop.pump()
        steps = loop.snapshot.tick.realised_steps
        if steps is not last:
            rebuilt += 1
            last = steps
            records = session.tick().realised_steps
            assert [s.side for s in steps] == [r.side for r in records]
            np.testing.assert_array_equal(
                [s.position for s in steps], [r.position for r in records]
            )
    assert session.metrics.ticks > 600 and landed == 6
    assert rebuilt == 1 + 6  # the first publish after the reset, then once per landing
    session.reset()  # a reset empties them
    session.step()
    loop.pump()
    assert loop.snapshot.tick.realised_steps == ()
