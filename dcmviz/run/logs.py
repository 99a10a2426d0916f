"""What the headless runner records of a walk: every tick's DCM error (:class:`TickLog`), one CSV
row per tick (``--csv``, :class:`CsvLog`) and the recovery from each push (:func:`push_recovery`).
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dcmviz.config import Push
from dcmviz.session import Tick

RECOVERY_THRESHOLDS_M = (0.01, 0.02)  # DCM error levels reported per push (1 cm, 2 cm)


@dataclass
class TickLog:
    """Time and DCM error of every tick (the session's history is a bounded ring buffer)."""

    t: list[float] = field(default_factory=list)
    error: list[float] = field(default_factory=list)

    def __call__(self, tick: Tick) -> None:
        self.t.append(tick.t)
        self.error.append(tick.dcm_error_m)  # this tick's |ξ − ξ_ref|


CSV_VECTORS = ("xi", "xi_ref", "xi_adj", "v_ref", "v_cmd", "com", "f_ext", "f_hat")
CSV_COLUMNS = ("t", *(f"{v}_{a}" for v in CSV_VECTORS for a in "xyz"), "support")


class CsvLog:
    """``--csv``: one row per control tick, written as the walk runs (columns ``CSV_COLUMNS``).

    ``xi``/``xi_ref``/``xi_adj``/``v_ref``/``v_cmd`` are the walker's (eqs. 1, 48, 33, 47, 41),
    ``com`` the measured CoM after the tick, ``f_ext`` the applied and ``f_hat`` the estimated
    external force (N), ``support`` the scheduled support (``left``/``right``/``double``).
    """

    def __init__(self, path: str | Path) -> None:
        self._file = open(path, "w", newline="", encoding="utf-8")  # noqa: SIM115 - closed in close()
        self._writer = csv.writer(self._file)
        self._writer.writerow(CSV_COLUMNS)

    def __call__(self, tick: Tick) -> None:
        c = tick.command
        row: list[Any] = [repr(tick.t)]
        for v in (c.xi, c.xi_ref, c.xi_adj, c.v_ref, c.v_cmd, tick.state.com, tick.f_ext, c.f_hat):
            row += [repr(float(v[0])), repr(float(v[1])), repr(float(v[2]))]
        row.append(tick.support)
        self._writer.writerow(row)

    def close(self) -> None:
        self._file.close()


def push_recovery(
    pushes: Sequence[Push],
    t: np.ndarray,
    error: np.ndarray,
    touchdowns: Sequence[float],
    fall_time_s: float | None,
) -> list[dict[str, Any]]:
    """Per push: peak DCM error, and how long / how many steps until it is back under 1 and 2 cm.

    A push's window runs from its start to the next push's start (or the end of the run).  The
    error is "back under" a threshold at the first instant after the push ends from which it stays
    below the threshold to the end of the window; ``None`` if it never does (or the robot fell).
    Steps are touchdowns after the push ends, up to that instant.
    """
    order = sorted(range(len(pushes)), key=lambda i: pushes[i].start)
    t_run_end = float(t[-1]) if len(t) else 0.0
    touch = np.asarray(sorted(touchdowns), dtype=float)
    results: list[dict[str, Any]] = [{} for _ in pushes]
    for rank, i in enumerate(order):
        push = pushes[i]
        t0, t1 = push.start, push.start + push.duration
        w_end = pushes[order[rank + 1]].start if rank + 1 < len(order) else t_run_end + 1.0
        in_push = (t >= t0) & (t < t1)
        in_window = (t >= t0) & (t < w_end)
        res: dict[str, Any] = {
            "start_s": t0,
            "duration_s": push.duration,
            "force_n": list(push.force),
            "ramp_s": push.ramp,
            "impulse_ns": float(np.linalg.norm(push.force)) * (push.duration - 0.5 * push.ramp),
            "reached": bool(len(t) and t[-1] >= t0),
            "max_dcm_error_during_push_m": float(error[in_push].max()) if in_push.any() else None,
            "max_dcm_error_m": float(error[in_window].max()) if in_window.any() else None,
        }
        fell_in_window = fall_time_s is not None and fall_time_s < w_end
        after = (t >= t1) & (t < w_end)
        for thr in RECOVERY_THRESHOLDS_M:
            key = f"{round(thr * 100)}cm"
            t_rec: float | None = None
            if after.any() and not fell_in_window:
                ta, ea = t[after], error[after]
                above = np.nonzero(ea >= thr)[0]
                if len(above) == 0:
                    t_rec = t1
                elif above[-1] + 1 < len(ta):
                    t_rec = float(ta[above[-1] + 1])
            res[f"recovery_time_{key}_s"] = None if t_rec is None else t_rec - t1
            res[f"recovery_steps_{key}"] = (
                None if t_rec is None else int(np.count_nonzero((touch > t1) & (touch <= t_rec)))
            )
        results[i] = res
    return results
