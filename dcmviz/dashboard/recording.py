"""A rerun recording of the running session, kept in memory and offered as a download."""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr

LOG_DT_S = 0.01  # sim seconds between logged samples


class RerunCapture:
    """Called after every tick (``Session.on_tick``); logs the DCMs, VRP, CoM and forces."""

    def __init__(self, name: str = "dcmviz") -> None:
        self.stream = rr.RecordingStream("dcmviz", recording_id=None)
        self.memory = self.stream.memory_recording()
        self.name = name
        self._next_t = -np.inf
        self.samples = 0

    def __call__(self, session: Any) -> None:
        cmd = session.last_command
        t = float(session.t)
        if cmd is None or t < self._next_t:
            return
        self._next_t = t + LOG_DT_S
        rec = self.stream
        rec.set_time("sim_time", duration=t)
        for key in ("xi", "xi_ref", "xi_adj", "v_cmd", "v_ref", "f_hat"):
            rec.log(f"plots/{key}", rr.Scalars(np.asarray(getattr(cmd, key), dtype=float)))
        rec.log("plots/dcm_error", rr.Scalars([float(np.linalg.norm(cmd.xi - cmd.xi_ref))]))
        forces = session.external_force()
        total = sum((np.asarray(f, float) for f in forces.values()), np.zeros(3))
        rec.log("plots/f_ext", rr.Scalars(total))
        rec.log("world/com", rr.Points3D([session.last_state.com], radii=0.03))
        rec.log("world/dcm", rr.Points3D([cmd.xi], radii=0.02, colors=[0, 170, 255]))
        rec.log("world/vrp", rr.Points3D([cmd.v_cmd], radii=0.02, colors=[255, 200, 0]))
        self.samples += 1

    def finish(self) -> bytes:
        """The .rrd bytes recorded so far."""
        self.stream.flush()
        return self.memory.drain_as_bytes()
