"""The status line above the panel: preset, robot, backend, time, speed, falls, walk state, and
for a few seconds after a config change what it did ("gains changed (walk continues)" or
"restarted: gait changed").

The render thread writes it whenever anything but the clock changed (the walk state, a fall, the
warnings, a push) in the same frame as the scene, so the line, the panel and the 3-D view always
tell the same; the clock alone is rewritten at most once a second.
"""

from __future__ import annotations

from collections.abc import Callable

import viser

from dcmviz.dashboard.loop import Snapshot

NOTE_SHOW_S = 5.0  # wall seconds a change's note stays in the status line


def walk_state(snap: Snapshot) -> str:
    st = snap.status
    if st.fallen:
        return "fallen (resetting)"
    if st.held and st.playing:
        return "about to walk"
    if st.frame is not None:
        return "playing back the buffer" if st.playing else "paused (scrubbed back)"
    if not st.playing:
        return f"paused: {st.paused_reason}" if st.paused_reason else "paused"
    if snap.tick is not None and snap.tick.done:
        return "standing (plan done)"
    return "walking"


class StatusLine:
    """Writes the status markdown; :meth:`show` is called by the render thread."""

    def __init__(
        self,
        handle: viser.GuiMarkdownHandle,
        name: Callable[[], str],
        extra: Callable[[Snapshot], str] | None = None,
    ) -> None:
        self.handle = handle
        self.name = name  # the current preset's name
        self.extra = extra  # further lines (feasibility warnings, a push, advice after falls)
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

    def text(self, snap: Snapshot, fps: float, now: float, *, clock: bool = True) -> str:
        """The markdown; without ``clock`` the numbers that change every frame are left out
        (what the render thread compares to decide whether to write at once)."""
        st = snap.status
        live = st.playing and not st.fallen and not st.held and st.frame is None
        if clock:
            speed = f"real-time ×{st.real_time_factor:4.2f} · {fps:4.1f} fps · " if live else ""
            t = f"t = {st.t:6.2f} s · "
        else:
            speed, t = ("…" if live else ""), ""
        note = self.note(snap, now)
        extra = self.extra(snap) if self.extra is not None else ""
        robot = st.robot.name if st.robot else ""
        return (
            f"**{self.name()}** · {robot} · {st.backend}  \n"
            f"{t}{speed}falls {st.falls} · {walk_state(snap)}"
            + (f"  \nlast change: *{note}*" if note else "")
            + (f"  \n{extra}" if extra else "")
        )

    def show(self, snap: Snapshot, fps: float, now: float) -> None:
        text = self.text(snap, fps, now)
        if self.handle.content != text:
            self.handle.content = text
