"""A walking session: preset → plan → walker → backend (:mod:`.session`), and the one per-tick
record every shell reads (:mod:`.tick`) with the names and colours of its signals
(:mod:`.signals`)."""

from dcmviz.session.session import (
    HISTORY,
    HISTORY_KEYS,
    Metrics,
    Session,
    SessionState,
    make_backend,
)
from dcmviz.session.tick import AppliedPush, Pull, Tick

__all__ = [
    "HISTORY",
    "HISTORY_KEYS",
    "AppliedPush",
    "Metrics",
    "Pull",
    "Session",
    "SessionState",
    "Tick",
    "make_backend",
]
