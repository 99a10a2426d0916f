"""The Time folder: play/pause, single steps (a tick, a footstep), scrubbing the buffer, resuming
from the frame shown, and pausing right after a push.

Every control posts a command into the simulation loop (which owns time); :meth:`TimePanel.show`
writes what a snapshot says back into the controls (called by the render thread).
"""

from __future__ import annotations

import threading
import time

import viser

from dcmviz.dashboard.loop import SimLoop, Snapshot
from dcmviz.dashboard.timeline import BUFFER_S

STEP_BUTTONS = ("◀◀ footstep", "◀ tick", "tick ▶", "footstep ▶▶")
STEPS = {
    "◀◀ footstep": ("footstep", -1),
    "◀ tick": ("tick", -1),
    "tick ▶": ("tick", +1),
    "footstep ▶▶": ("footstep", +1),
}
SCRUB_STEP_S = 0.01  # the scrub slider's resolution (single ticks: the step buttons)
USER_SCRUB_HOLD_S = 0.5  # after a tab moved the slider, the server does not move it back


class TimePanel:
    """Handles ``gui_play``, ``gui_steps``, ``gui_scrub``, ``gui_resume``, ``gui_live``,
    ``gui_frame`` and ``gui_pause_after``."""

    def __init__(self, gui: viser.GuiApi, loop: SimLoop) -> None:
        self.loop = loop
        self._quiet = threading.local()
        self._written_at = 0.0  # update_timestamp of the scrub slider's last server write
        with gui.add_folder("Time", expand_by_default=True):
            self.gui_play = gui.add_button(
                "Pause", icon=viser.Icon.PLAYER_PAUSE,
                hint="Pause or play; playing from a frame in the past plays the buffer back "
                "up to now, then simulates on",
            )  # fmt: skip
            self.gui_play.on_click(lambda event: self.on_play(not self.loop.playing))
            self.gui_steps = gui.add_button_group("step", STEP_BUTTONS)
            self.gui_steps.on_click(lambda event: self.on_step(event.target.value))
            self.gui_scrub = gui.add_slider(
                "time back [s]", min=-BUFFER_S, max=0.0, step=SCRUB_STEP_S, initial_value=0.0,
                hint=f"Drag back through the last {BUFFER_S:.0f} s: the robot, footsteps and "
                "plots follow (0 = now)",
            )  # fmt: skip
            self.gui_scrub.on_update(self._scrubbed)
            self.gui_resume = gui.add_button(
                "Resume from here", icon=viser.Icon.PLAYER_TRACK_NEXT, disabled=True,
                hint="Restart the simulation from the frame shown, exactly as it was there, "
                "with the gains set now (the later frames are dropped)",
            )  # fmt: skip
            self.gui_resume.on_click(lambda event: self.on_resume())
            self.gui_live = gui.add_button(
                "Back to now", icon=viser.Icon.PLAYER_SKIP_FORWARD, disabled=True,
                hint="Show the newest frame again (paused)",
            )  # fmt: skip
            self.gui_live.on_click(lambda event: self.loop.post("live"))
            self.gui_pause_after = gui.add_slider(
                "pause after push [s]", min=0.0, max=3.0, step=0.05, initial_value=0.0,
                hint="> 0: the walk pauses by itself this long after each push starts, "
                "so you can step back through it (0 = off)",
            )  # fmt: skip
            self.gui_pause_after.on_update(
                lambda event: self.loop.post("pause_after_push", float(event.target.value))
            )
            self.gui_frame = gui.add_markdown("")
        self._shown: tuple = ()

    # -- callbacks ------------------------------------------------------------------------------
    def on_play(self, playing: bool) -> None:
        self.loop.post("play", playing)
        self.loop.playing = playing  # the button label follows at once
        self._label(playing)

    def _label(self, playing: bool) -> None:
        label = "Pause" if playing else "Play"
        if self.gui_play.label != label:
            self.gui_play.label = label
            self.gui_play.icon = viser.Icon.PLAYER_PAUSE if playing else viser.Icon.PLAYER_PLAY

    def on_step(self, which: str) -> None:
        if which in STEPS:
            self.loop.post("step", STEPS[which])

    def on_seek(self, seconds_back: float) -> None:
        self.loop.post("seek", max(0.0, float(seconds_back)))

    def on_resume(self) -> None:
        self.loop.post("resume")

    def _scrubbed(self, event: viser.GuiEvent) -> None:
        if event.client is None or getattr(self._quiet, "on", False):
            return  # the server moved it (show)
        self.on_seek(-float(event.target.value))

    # -- what a snapshot says -------------------------------------------------------------------
    def show(self, snap: Snapshot) -> None:
        """The play button, the slider at the frame shown, the frame's line (render thread)."""
        st = snap.status
        self._label(st.playing)
        back = round(st.frame_back_s, 2) if st.frame is not None else 0.0
        stamp = self.gui_scrub.update_timestamp  # a tab's value since the last write: its own
        by_tab = stamp > self._written_at and time.time() - stamp < USER_SCRUB_HOLD_S
        value = -min(back, BUFFER_S)
        if not by_tab and abs(self.gui_scrub.value - value) > SCRUB_STEP_S / 2:
            self._quiet.on = True
            try:
                self.gui_scrub.value = value
                self._written_at = self.gui_scrub.update_timestamp
            finally:
                self._quiet.on = False
        scrubbed = st.frame is not None
        if self.gui_live.disabled == scrubbed:
            self.gui_live.disabled = not scrubbed
        can_resume = not st.playing and st.buffer_s > 0
        if self.gui_resume.disabled == can_resume:
            self.gui_resume.disabled = not can_resume
        text = frame_text(snap)
        if text != self._shown:
            self._shown = text
            self.gui_frame.content = text


def frame_text(snap: Snapshot) -> str:
    """One line: the frame shown (its time and how far back) and what the buffer holds."""
    st = snap.status
    if st.frame is not None:
        where = f"frame t = {st.t:.3f} s, {st.frame_back_s:.2f} s back"
    elif st.playing:
        where = "now (live)"  # the status line has the clock: no message per frame here
    else:
        where = f"now: t = {st.t:.3f} s"
    return (
        f"<small>{where} · buffer {int(st.buffer_s)} s of {BUFFER_S:.0f} s "
        f"({st.buffer_bytes / 1e6:.0f} MB)</small>"
    )
