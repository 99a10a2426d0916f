"""The status line above the panel: preset, robot, backend, time, speed, falls, walk state, and
for a few seconds after a config change what it did ("gains changed (walk continues)" or
"restarted: gait changed")."""

from __future__ import annotations

from collections.abc import Callable

import viser

from dcmviz.dashboard.loop import Snapshot

NOTE_SHOW_S = 5.0  # wall seconds a change's note stays in the status line


def walk_state(snap: Snapshot) -> str:
    if snap.status.fallen:
        return "fallen"
    if snap.status.held and snap.status.playing:
        return "about to walk"
    if snap.tick is not None and snap.tick.done:
        return "standing (plan done)"
    return "walking" if snap.status.playing else "paused"


class StatusLine:
    """Writes the status markdown; :meth:`show` is called by the render thread."""

    def __init__(
        self,
        handle: viser.GuiMarkdownHandle,
        name: Callable[[], str],
        extra: Callable[[], str] | None = None,
    ) -> None:
        self.handle = handle
        self.name = name  # the current preset's name
        self.extra = extra  # further lines (feasibility warnings, what a click pushes)
        self._note_seq = 0
        self._note_since = -float("inf")

    def note(self, snap: Snapshot, now: float) -> str:
        """The snapshot's note while it is fresh (shown from the first time it is seen)."""
        if snap.status.note_seq != self._note_seq:
            self._note_seq = snap.status.note_seq
            self._note_since = now
        return snap.status.note if now - self._note_since < NOTE_SHOW_S else ""

    def is_new(self, snap: Snapshot) -> bool:
        """A config change was noted since the line was last written."""
        return snap.status.note_seq != self._note_seq

    def text(self, snap: Snapshot, fps: float, now: float) -> str:
        speed = (
            f"real-time ×{snap.status.real_time_factor:4.2f} · {fps:4.1f} fps · "
            if snap.status.playing and not snap.status.fallen and not snap.status.held
            else ""
        )
        note = self.note(snap, now)
        extra = self.extra() if self.extra is not None else ""
        return (
            f"**{self.name()}** · {snap.status.robot.name if snap.status.robot else ''} · {snap.status.backend}  \n"
            f"t = {snap.status.t:6.2f} s · {speed}falls {snap.status.falls} · {walk_state(snap)}"
            + (f"  \nlast change: *{note}*" if note else "")
            + (f"  \n{extra}" if extra else "")
        )

    def show(self, snap: Snapshot, fps: float, now: float) -> None:
        text = self.text(snap, fps, now)
        if self.handle.content != text:
            self.handle.content = text
