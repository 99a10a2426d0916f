"""The walker: the per-tick loop of §III (:mod:`.walker`) and what flows between it and a backend
(:mod:`.state`)."""

from dcmviz.walker.state import FootTarget, MeasuredState, WalkerCommand, WalkerStatus
from dcmviz.walker.walker import Walker

__all__ = ["FootTarget", "MeasuredState", "WalkerCommand", "WalkerStatus", "Walker"]
