"""Issue 25 end-to-end in a real headless Chromium: the dashboard as a tuning engineer lives it.

One server (point mass, for speed) and one page for the module, the tests in the order a user
would go: pause right after a push, step and scrub back through it (ξ leaves ξ_ref, a footstep
moves), keep the preview as A, resume from there with another gain, compare; drag the robot;
choose plot signals; the camera; the defects of the issue (reset or reload while paused, falls
in a loop, b typed beyond its range, push settings per robot, recordings, sweep exports).
Screenshots go to ``$DCMVIZ_SCREENSHOTS`` (default: a pytest tmp dir).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser

viser = pytest.importorskip("viser")
sync_api = pytest.importorskip("playwright.sync_api")

from helpers import free_port, wait_for  # noqa: E402
from test_dashboard_browser import aim_camera_at as aim_client_camera  # noqa: E402
from test_dashboard_browser import (  # noqa: E402
    click_through,
    close_notifications,
    pixels_of,
    project,
)
from test_fig1a import drawn_trace, fig1a_frame  # noqa: E402

from dcmviz.config import Config  # noqa: E402
from dcmviz.dashboard import Dashboard  # noqa: E402
from dcmviz.dashboard import scene as draw  # noqa: E402
from dcmviz.dashboard.headless import CHROMIUM, launch_chromium  # noqa: E402

PRESETS = Path(__file__).resolve().parents[1] / "presets"

if not os.path.exists(CHROMIUM):
    pytest.skip("Debian chromium is not installed", allow_module_level=True)


@pytest.fixture(scope="module")
def app() -> Iterator[Dashboard]:
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    dashboard = Dashboard(server, Config().replace(sim={"backend": "lip"}), presets_dir=PRESETS)
    yield dashboard
    dashboard.stop()
    server.stop()


@pytest.fixture(scope="module")
def page(app: Dashboard) -> Iterator:
    with sync_api.sync_playwright() as p:
        browser = launch_chromium(p)
        page = browser.new_page(viewport={"width": 1200, "height": 760}, accept_downloads=True)
        page.goto(f"http://127.0.0.1:{app.server.get_port()}")
        page.get_by_text("T_ss [s]").wait_for(timeout=60_000)
        assert wait_for(lambda: any(c.camera.image_width > 0 for c in clients(app)), 30)
        yield page
        browser.close()


def clients(app: Dashboard) -> list:
    return list(app.server.get_clients().values())


def box(page, handle, tab: str | None = None):
    """The number box of a slider (or the text box of a text input) by its handle."""
    root = page.locator(f"[id='{handle._impl.uuid}']").locator("xpath=..")
    found = root.locator("input:not([type=hidden])").first
    if tab is not None and not found.is_visible():
        click_through(page, page.get_by_role("tab", name=tab, exact=True))
    found.wait_for(state="visible", timeout=15_000)
    return found


def type_into(page, handle, text: str, tab: str | None = None) -> None:
    field = box(page, handle, tab)
    field.fill(text)
    field.press("Enter")


def button(page, name: str, tab: str | None = None):
    found = page.get_by_role("button", name=name, exact=True).first
    if tab is not None and not found.is_visible():
        click_through(page, page.get_by_role("tab", name=tab, exact=True))
    return found


def status(page) -> str:
    return page.locator("body").text_content(timeout=20_000) or ""


def fresh_walk(app: Dashboard, t: float = 1.0) -> None:
    """The walk from its start, playing, at least ``t`` s into it."""
    loop = app.loop
    resets = loop.resets
    loop.post("reset")
    app.time_panel.on_play(True)
    assert wait_for(lambda: loop.resets > resets and loop.playing, 10)
    assert wait_for(lambda: loop.session.t > t, 30)


# -- pause right after a push, step and scrub back through it ---------------------------------


def test_pause_after_a_push_then_step_and_scrub_back_through_it(page, app, shots) -> None:
    """Item 4: "pause after push" set in the page pauses the walk at the push's start + that
    time exactly (sim time: no race with a click); typing a time back into the scrub box shows
    that frame (status line, scene, plots follow); the step buttons move one tick and one
    footstep; back through the push ξ leaves ξ_ref and a footstep is adjusted."""
    loop = app.loop
    fresh_walk(app, 3.0)  # two footsteps landed (at 1.7 and 2.6 s)
    app.time_panel.on_play(False)  # (a slow page takes seconds per click: set up while paused)
    assert wait_for(lambda: not loop.snapshot.status.playing)
    type_into(page, app.time_panel.gui_pause_after, "0.6")
    assert wait_for(lambda: loop.pause_after_push_s == 0.6)
    app.push_panel.gui_push_magnitude.value = 150.0
    app.push_panel.gui_push_direction.value = 90.0
    n, notes = len(loop.session.pushes), len(app.notifications)
    click_through(page, button(page, "Push", tab="Simulate"))
    assert wait_for(lambda: len(loop.session.pushes) == n + 1, 10), (
        list(app.notifications)[notes:],
        loop.resets,
        loop.session.t,
    )
    push = loop.session.pushes[-1]
    assert push.start == loop.session.t  # it starts where the walk stands
    click_through(page, page.get_by_role("button", name="Play"))
    assert wait_for(lambda: loop.playing, 10)
    assert wait_for(lambda: not loop.playing, 20)
    dt = loop.timeline.dt
    assert push.start + 0.6 - 1e-9 <= loop.session.t < push.start + 0.6 + dt  # exactly then
    page.get_by_text("paused after the push").first.wait_for(timeout=15_000)
    t_paused = loop.session.t

    type_into(page, app.time_panel.gui_scrub, "-0.5", tab=None)  # 0.5 s back: in the push
    assert wait_for(lambda: app.loop.snapshot.status.frame is not None, 10)
    snap = app.loop.snapshot
    assert snap.status.t == pytest.approx(t_paused - 0.5, abs=0.011)
    assert wait_for(
        lambda: app.view.drawn is not None and app.view.drawn.status.frame == snap.status.frame
    )
    # the scene shows that frame: the ball at its CoM; the plot window ends there
    np.testing.assert_allclose(app.view._markers["com"].position, snap.tick.state.com, atol=1e-3)
    t_plot = np.asarray(app.live_plot.signals.data[0])
    assert t_plot[-1] == pytest.approx(snap.status.t, abs=0.011)
    page.get_by_text(re.compile(r"frame t = \d+\.\d+ s, 0\.50 s back")).first.wait_for(
        timeout=10_000
    )
    page.get_by_text("paused (scrubbed back)").first.wait_for(timeout=10_000)
    # the push shows: ξ leaves ξ_ref in the window (the plot's own data) while the force acts
    history = snap.history
    in_push = (history["t"] >= push.start) & (history["t"] <= snap.status.t)
    before = history["t"] < push.start
    gap = np.linalg.norm(history["xi"] - history["xi_ref"], axis=1)
    assert gap[in_push].max() > 3 * max(gap[before].max(), 1e-3)
    page.screenshot(path=shots / "t1_scrubbed_into_the_push.png")

    frame = snap.status.frame
    click_through(page, page.get_by_role("button", name="◀ tick"))
    assert wait_for(lambda: app.loop.snapshot.status.frame == frame - 1, 10)
    assert app.loop.snapshot.status.t == pytest.approx(snap.status.t - dt, abs=1e-4)
    click_through(page, page.get_by_role("button", name="tick ▶"))
    assert wait_for(lambda: app.loop.snapshot.status.frame == frame, 10)
    # a footstep back: the first frame after a landing (one more footstep landed than before)
    click_through(page, page.get_by_role("button", name="◀◀ footstep"))
    assert wait_for(lambda: (app.loop.snapshot.status.frame or frame) < frame, 10)
    landed = app.loop.snapshot.status.frame
    before_landing = app.loop.timeline.tick(landed - 1)
    assert app.loop.snapshot.tick.steps_completed == before_landing.steps_completed + 1

    # a footstep adjusted by the push: some frame between the push and the pause has a ghost,
    # and the scene draws it when that frame is shown
    from dcmviz.dashboard.loop import Snapshot
    from dcmviz.dashboard.render import ghost_steps

    seqs = range(landed, app.loop.timeline.last_seq + 1)
    ghosted = [s for s in seqs if ghost_steps(Snapshot(tick=app.loop.timeline.tick(s)))]
    assert ghosted, "step adjustment moved no footstep"
    last, shown = app.loop.timeline.last_seq, ghosted[len(ghosted) // 2]
    app.time_panel.on_seek((last - shown) * dt)
    assert wait_for(lambda: app.loop.snapshot.status.frame == shown, 10)
    assert wait_for(lambda: app.view._steps_drawn.get("adjusted", ("", ()))[1] != (), 10)
    page.screenshot(path=shots / "t2_adjusted_footstep.png")


def test_keep_a_preview_then_resume_from_here_with_another_gain(page, app, shots) -> None:
    """Item 4 and the issue's "done when": scrubbed back into the push, the walked preview is
    kept as A (grey in 3-D and in Fig. 1a); k_ξ typed in the page; "Resume from here" restarts
    the physics at that frame (its physical state the buffered one bit for bit) with the new
    gain, which every following command obeys (eq. 41); the new walked preview is drawn against
    A."""
    loop = app.loop
    assert loop.cursor is not None and not loop.playing  # where the last test left it
    folder = page.get_by_text("Compare (A/B)").first
    click_through(page, page.get_by_role("tab", name="Plan", exact=True))
    if not page.get_by_role("button", name="Keep this preview as A").is_visible():
        click_through(page, folder)
    click_through(page, page.get_by_role("button", name="Keep this preview as A"))
    assert wait_for(lambda: app.preview.kept is not None, 10)
    kept = app.preview.kept
    page.get_by_text("A: the preview at t =").first.wait_for(timeout=10_000)
    # A's traces in Fig. 1a's frame as plotly.js drew them: A's DCM on the preview's times
    frame = fig1a_frame(page)
    assert wait_for(lambda: frame.evaluate("window.__fig1a.figure.data.length") == 12, 10)
    for row in (1, 2, 3):
        t, ghost = drawn_trace(frame, "A: ξ", row)
        np.testing.assert_allclose(ghost, np.interp(t, kept.t, kept.dcm[:, row - 1]), atol=2e-5)
    assert draw.shown(app.server.scene, "/kept", (), ("kept",))  # A drawn in 3-D
    k_before = loop.session.config.control.k_xi
    type_into(page, app.controls.handles[("control", "k_xi")], "6", tab="Plan")
    assert wait_for(
        lambda: app.config.control.k_xi == 6.0 and loop.session.config.control.k_xi == 6.0, 10
    )
    assert loop.cursor is not None  # a gain change keeps the frame shown
    # the frame resumed is the cursor's (the snapshot, published at 60 Hz, may still show the
    # frame before the previous test's last scrub: 10 ms earlier)
    frame_t = loop.timeline.time_of(loop.cursor)
    ticks: list = []
    unsubscribe = loop.session.subscribe(lambda tick: ticks.append(tick))
    try:
        click_through(page, page.get_by_role("button", name="Resume from here"))
        assert wait_for(lambda: loop.resumes == 1, 15)
        assert "not exact" not in loop.note
        shown = re.search(r"resumed from t = (\d+\.\d+) s", loop.note)  # t to 0.01 s
        assert shown is not None and abs(float(shown.group(1)) - frame_t) <= 0.005 + 1e-6
        page.get_by_text(re.compile(r"resumed from t = \d+\.\d+ s")).first.wait_for(timeout=10_000)
        assert wait_for(lambda: len(ticks) > 200, 20)
    finally:
        unsubscribe()
    assert ticks[0].t == pytest.approx(frame_t + loop.timeline.dt, abs=0.011)
    assert k_before != 6.0
    for tick in ticks:  # eq. (41) with the new gain
        cmd = tick.command
        b = loop.session.config.dcm.b
        np.testing.assert_allclose(
            cmd.v_cmd, cmd.v_ref + (1 + 6.0 * b) * (cmd.xi - cmd.xi_adj), atol=1e-12
        )
    # A stays drawn against the new walked preview (B), which differs from it
    assert app.preview.kept is kept
    assert wait_for(lambda: app.preview.data is not None and app.preview.data is not kept, 10)
    page.screenshot(path=shots / "t3_resumed_against_A.png")
    type_into(page, app.controls.handles[("control", "k_xi")], "3", tab="Plan")
    click_through(page, page.get_by_role("button", name="Clear A"))
    assert wait_for(lambda: app.preview.kept is None, 10)
    type_into(page, app.time_panel.gui_pause_after, "0", tab=None)
    assert wait_for(lambda: loop.pause_after_push_s == 0.0)


# -- drag, plots, camera -----------------------------------------------------------------------


def aim_camera_at(app: Dashboard, page, point: np.ndarray) -> tuple[float, float]:
    """Set the tab's camera to look at ``point`` from behind-left; returns its pixel in the page
    once the tab reports that camera for its canvas."""
    return aim_client_camera(app, clients(app)[-1], page, point, timeout=20)


def test_dragging_the_robot_pulls_it_with_a_spring(page, app, shots) -> None:
    """Item 4: pressing on the point mass and dragging pulls it with a spring towards the
    pointer: the ticks carry the pull and its force on the torso (k times the stretch, the
    stretch along the drag), the scene draws the spring, the status says it; letting go ends
    it and logs it."""
    loop = app.loop
    fresh_walk(app, 1.0)
    app.follow_was = app.gui_follow.value
    app.gui_follow.value = False  # the camera stays where the drag is measured
    app.time_panel.on_play(False)
    assert wait_for(lambda: not loop.snapshot.status.playing)
    com = np.asarray(loop.snapshot.com)
    x, y = aim_camera_at(app, page, com)
    assert wait_for(lambda: close_notifications(page), 15)
    clip = {"x": x - 10, "y": y - 10, "width": 20, "height": 20}
    assert wait_for(lambda: (pixels_of(page, clip).mean(axis=2) < 190).mean() > 0.3, 15)
    app.time_panel.on_play(True)
    ticks: list = []
    unsubscribe = loop.session.subscribe(ticks.append)
    drags = app.push_panel.drags
    try:
        page.mouse.move(x, y)
        page.mouse.down()
        page.mouse.move(x + 8, y, steps=2)
        page.mouse.move(x + 18, y + 1, steps=3)  # to the right of the view: the robot's −y
        assert wait_for(lambda: any(t.pull is not None for t in ticks), 15)
        assert wait_for(lambda: app.view._markers["spring"].visible, 10)
        page.get_by_text(re.compile(r"pulling torso: \d+ N")).first.wait_for(timeout=10_000)
        page.screenshot(path=shots / "t4_drag_push.png")
    finally:
        page.mouse.up()
        unsubscribe()
    assert app.push_panel.drags == drags + 1
    pulled = [t for t in ticks if t.pull is not None]
    stretched = 0
    for tick in pulled:
        (push,) = [p for p in tick.pushes if p.body == "torso"]
        stretch = tick.pull.target - tick.pull.grab(push.point)
        if np.linalg.norm(stretch) < 0.01:
            continue  # (the drag's first events: no stretch yet)
        # the spring's force: k (target − grab point) − c (its velocity); the damping is less
        # than the spring's part: along the stretch
        assert np.dot(push.force, stretch) > 0
        stretched += 1
    assert stretched > 10
    assert np.mean([t.pull.target[1] - t.state.com[1] for t in pulled]) < 0  # towards −y
    assert wait_for(lambda: app.push_panel.pulls, 15)  # let go (the drag's end reached us)
    assert "pulled torso for" in app.push_panel.pulls[-1]
    assert wait_for(lambda: getattr(loop.snapshot.tick, "pull", None) is None, 10)
    assert wait_for(lambda: not app.view._markers["spring"].visible, 10)
    app.gui_follow.value = app.follow_was


def test_plot_signals_and_window_are_chosen_in_the_page(page, app) -> None:
    """Item 4: the Live tab's checkboxes choose the plotted signals (F_ext on, ξ_ref off) and
    its window box the seconds plotted (of the buffer)."""
    click_through(page, page.get_by_role("tab", name="Live"))
    for key, want in (("f_ext", True), ("xi_ref", False)):  # F_ext on, ξ_ref off
        handle = app.live_handles[key]
        if handle.value != want:
            click_through(page, page.locator(f"[id='{handle._impl.uuid}']"))
        assert wait_for(lambda k=key, w=want: app.live_plot.shown[k] == w, 10)
        index = 1 + list(app.live_plot.shown).index(key)
        assert wait_for(lambda i=index, w=want: app.live_plot.signals.series[i]["show"] == w, 10)
    # the window lies within one walk: 6 s into a fresh one, paused there (a plan walk starts
    # over soon after its last step; typing the window while it walked on could put the
    # buffer's end into the next walk, 2.2 s long when this ran under load)
    fresh_walk(app, 6.0)
    app.time_panel.on_play(False)
    assert wait_for(lambda: not app.loop.snapshot.status.playing)
    type_into(page, app.live_handles["window"], "5")
    assert wait_for(lambda: app.loop.plot_window_s == 5.0, 10)

    def span() -> float:  # of the history the paused loop publishes
        t = app.loop.snapshot.history["t"] if app.loop.snapshot.history else [0.0]
        return float(t[-1] - t[0])

    assert wait_for(lambda: span() == pytest.approx(5.0, abs=0.05), 10), span()
    assert wait_for(
        lambda: np.ptp(np.asarray(app.live_plot.signals.data[0])) == pytest.approx(5.0, abs=0.05),
        10,
    )
    type_into(page, app.live_handles["window"], "8")
    app.time_panel.on_play(True)
    click_through(page, page.get_by_role("tab", name="Preview (Fig. 1a)"))


def test_camera_follows_by_default_and_frames_the_robot(page, app) -> None:
    """Defect 7: the camera follows the robot from the start (the checkbox ticked in the page)
    and the Frame robot button looks at it; the scene's legend is above the tabs, in sight
    whichever tab is open."""
    client = clients(app)[-1]
    follow = page.locator(f"[id='{app.gui_follow._impl.uuid}']")
    assert app.gui_follow.value is True
    fresh_walk(app, 0.5)
    x0 = float(client.camera.position[0])
    assert wait_for(lambda: float(client.camera.position[0]) > x0 + 0.2, 30)  # walks along +x
    click_through(page, page.get_by_role("button", name="Frame robot"))

    def framed() -> bool:  # looking at the robot (beside it: the free part of the page)
        aim = np.asarray(client.camera.look_at)[:2] - draw.FRAME_SHIFT
        return bool(np.abs(aim - np.asarray(app.loop.snapshot.com)[:2]).max() < 0.25)

    assert wait_for(framed, 15), (
        client.camera.look_at,
        client.camera.position,
        app.loop.snapshot.com,
        draw.FRAME_SHIFT,
    )
    for tab in ("Simulate", "Presets", "Plan"):
        click_through(page, page.get_by_role("tab", name=tab, exact=True))
        assert page.get_by_text("measured CoP, contact forces").first.is_visible()
    del follow


def test_the_dcm_and_vrp_dots_are_in_sight_from_the_first_view(page, app, shots) -> None:
    """Defect 7: from the first view's angle, ξ's dot (on its pin above the feet) is drawn in
    its colour where it projects: the feet no longer hide it."""
    client = clients(app)[-1]
    fresh_walk(app, 2.2)
    app.time_panel.on_play(False)
    assert wait_for(lambda: not app.loop.snapshot.status.playing)
    click_through(page, page.get_by_role("button", name="Frame robot"))
    shift = draw.FRAME_SHIFT[0]
    assert wait_for(
        lambda: abs(client.camera.look_at[0] - shift - app.loop.snapshot.com[0]) < 0.05, 15
    )
    dots = app.view._markers["dots"]
    xi_dot = np.asarray(dots.batched_positions)[0].astype(float)
    canvas = page.locator("canvas").first
    assert wait_for(
        lambda: (
            abs(
                client.camera.image_width / client.camera.image_height
                - canvas.bounding_box()["width"] / canvas.bounding_box()["height"]
            )
            < 0.01
        ),
        15,
    )
    u, v = project(client.camera, xi_dot)
    rect = canvas.bounding_box()
    clip = {"x": rect["x"] + u * rect["width"] - 5, "y": rect["y"] + v * rect["height"] - 5,
            "width": 10, "height": 10}  # fmt: skip
    assert wait_for(lambda: close_notifications(page), 15)

    def blue() -> bool:  # ξ's colour (0, 170, 255), lit: blue well above red
        r, g, b = pixels_of(page, clip).reshape(-1, 3).T
        return bool(((b > 150) & (b > r + 80)).any())

    assert wait_for(blue, 20)
    page.screenshot(path=shots / "t5_dots_in_sight.png")
    app.time_panel.on_play(True)


# -- the defects ---------------------------------------------------------------------------------


def test_reset_while_paused_keeps_the_robot_drawn(page, app) -> None:
    """Defect 1: a reset while paused shows the robot standing at the walk's start: the point
    mass's leg stays drawn from the ground to its CoM (it used to vanish, leaving the ball)."""
    fresh_walk(app, 1.0)
    app.time_panel.on_play(False)
    resets = app.loop.resets
    click_through(page, button(page, "Reset", tab="Simulate"))
    assert wait_for(lambda: app.loop.resets == resets + 1, 10)
    assert wait_for(
        lambda: app.view.drawn is not None and app.view.drawn.status.resets == resets + 1
    )
    snap = app.view.drawn
    assert snap.tick is None and not snap.status.playing
    leg = app.view._markers["lip_leg"]
    assert wait_for(lambda: leg.visible, 15)
    foot, top = np.asarray(leg.points)[0]
    np.testing.assert_allclose(top, snap.com, atol=1e-5)
    assert foot[2] == pytest.approx(0.0, abs=0.01)  # on the ground
    app.time_panel.on_play(True)


def test_reload_while_paused_keeps_the_walk_and_the_recording(page, app) -> None:
    """Defect 8 and item 4: reloading the only tab while paused (and recording) finds the walk
    where it was: same time, still paused, the recording still running."""
    fresh_walk(app, 1.2)
    click_through(page, page.get_by_role("tab", name="Presets", exact=True))
    click_through(page, page.locator(f"[id='{app.recording.gui_record._impl.uuid}']"))
    assert wait_for(lambda: app.recording.recorder is not None, 15)
    app.time_panel.on_play(False)
    assert wait_for(lambda: not app.loop.snapshot.status.playing)
    t, resets = app.loop.session.t, app.loop.resets
    page.reload()
    page.get_by_text("T_ss [s]").wait_for(timeout=60_000)
    assert wait_for(lambda: len(clients(app)) == 1, 30)
    time.sleep(1.0)
    assert app.loop.session.t == t and app.loop.resets == resets and not app.loop.playing
    assert app.recording.recorder is not None
    click_through(page, page.get_by_role("tab", name="Presets", exact=True))
    page.get_by_text(re.compile(r"● recording \d+ s")).first.wait_for(timeout=15_000)
    with page.expect_download(timeout=30_000) as info:
        click_through(page, page.locator(f"[id='{app.recording.gui_record._impl.uuid}']"))
    assert Path(info.value.path()).stat().st_size > 1000
    app.time_panel.on_play(True)


def test_recording_shows_its_length_and_streams_live_to_a_rerun_viewer(page, app, tmp_path) -> None:
    """Defect 9 and item 4: a running recording shows its elapsed time and size, and the
    address a rerun viewer connects to; `rerun download` (the viewer's protocol) receives the
    live stream while it runs."""
    fresh_walk(app, 0.5)
    click_through(page, page.get_by_role("tab", name="Presets", exact=True))
    click_through(page, page.locator(f"[id='{app.recording.gui_record._impl.uuid}']"))
    assert wait_for(lambda: app.recording.recorder is not None, 15)
    line = page.get_by_text(re.compile(r"live: rerun rerun\+http://127\.0\.0\.1:\d+/proxy"))
    line.first.wait_for(timeout=15_000)
    url = app.recording.recorder.url
    assert wait_for(lambda: re.search(r"\d+\.\d MB", app.recording.progress()), 10)
    rerun = Path(sys.executable).with_name("rerun")  # the CLI rerun-sdk installs beside Python
    viewer = subprocess.Popen(
        [str(rerun), "download", "-o", str(tmp_path), url],
        env={**os.environ, "RERUN_ANALYTICS": "false"},
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        assert wait_for(
            lambda: any(p.stat().st_size > 20_000 for p in tmp_path.glob("*.rrd")), 30
        ), "the viewer received no data"
    finally:
        viewer.terminate()
        viewer.wait(10)
    with page.expect_download(timeout=30_000):
        click_through(page, page.locator(f"[id='{app.recording.gui_record._impl.uuid}']"))
    assert app.recording.recorder is None


def test_falls_in_a_loop_pause_the_walk_and_name_the_setting(page, app, shots) -> None:
    """Defects 2 and 4, item 2: Δx = 0.45 m in T_ss = 0.15 s with T_ds = 0.03 s falls at once,
    again and again: after two falls in a row (no push) the walk pauses and the page says
    which setting to change; the real-time factor never goes negative; the header's count of
    warnings is the panel's."""
    loop = app.loop
    falls = loop.falls
    factors: list[float] = []
    unsubscribe = loop.session.subscribe(lambda tick: factors.append(loop.real_time_factor()))
    data = app.config.to_dict()
    data["gait"].update(step_length=0.45, t_ss=0.15, t_ds=0.03)
    from dcmviz.config import config_from_dict

    assert app.editor.apply_config(config_from_dict(data))
    app.time_panel.on_play(True)
    try:
        assert wait_for(lambda: loop.falls >= falls + 2 and not loop.playing, 40)
    finally:
        unsubscribe()
    time.sleep(2 * 1.0)  # the fallen robot's pause, then the reset
    assert not loop.playing and loop.falls == falls + 2  # stopped there
    assert min(factors) >= 0.0
    page.get_by_text(
        re.compile(r"2 falls in a row with these settings: the walk is paused\. Change gait\.\w+")
    ).first.wait_for(timeout=15_000)
    assert "×-" not in status(page)
    header = re.search(r"(\d+) feasibility warnings?", app.gui_status.content)
    panel = re.search(r"(\d+) feasibility warnings?", app.feasibility.gui_warnings.content)
    assert header and panel and header.group(1) == panel.group(1)
    page.screenshot(path=shots / "t6_falls_paused.png")
    data["gait"].update(step_length=0.2, t_ss=0.7, t_ds=0.2)
    assert app.editor.apply_config(config_from_dict(data))
    app.time_panel.on_play(True)
    assert wait_for(lambda: loop.playing and not loop.snapshot.status.paused_reason, 10)


def test_a_fall_after_a_push_names_the_push(page, app) -> None:
    """Defect 3: a fall right after a push is the push's, not a footstep's."""
    fresh_walk(app, 1.5)
    app.push_panel.gui_push_magnitude.value = 2500.0
    app.push_panel.gui_push_duration.value = 0.3
    falls = app.loop.falls
    click_through(page, button(page, "Push", tab="Simulate"))
    assert wait_for(lambda: app.loop.falls == falls + 1, 20)
    page.get_by_text(
        re.compile(r"Likely cause: the push on the torso at t = \d+\.\d+ s \(2500 N")
    ).first.wait_for(timeout=15_000)
    app.push_panel.gui_push_magnitude.value = 150.0
    app.push_panel.gui_push_duration.value = 0.2


def test_b_typed_beyond_its_range_is_clamped_and_said(page, app) -> None:
    """Defect 5: b typed beyond what the robot walks at is clamped to the slider's end (what
    validation accepts) and the page says what was typed and what it became."""
    handle = app.controls.handles[("dcm", "b")]
    assert (handle.min, handle.max) == (0.271, 0.302)
    type_into(page, handle, "0.35", tab="Plan")
    page.get_by_text("b [s] = 0.35 is not allowed here: set to 0.302").first.wait_for(
        timeout=15_000
    )
    assert wait_for(lambda: app.config.dcm.b == 0.302, 10)
    type_into(page, handle, "0.3", tab="Plan")
    assert wait_for(lambda: app.config.dcm.b == 0.3, 10)


def test_push_settings_follow_the_robot(page, app) -> None:
    """Defect 9: another robot gets its own push force (by its mass), and the page says so."""
    app.push_panel.gui_push_magnitude.value = 500.0
    robot = app.controls.handles[("robot", "model")]
    click_through(page, page.get_by_role("tab", name="Simulate", exact=True))
    app.editor.on_field_change("robot", "model", "g1")
    assert wait_for(lambda: app.config.robot.model == "g1", 15)
    assert wait_for(lambda: app.push_panel.gui_push_magnitude.value == 55.0, 10), (
        app.push_panel.gui_push_magnitude.value,
        app.config.robot.model,
        list(app.notifications)[-3:],
    )
    page.get_by_text("|F| = 55 N for the 33 kg g1").first.wait_for(timeout=15_000)
    assert box(page, app.push_panel.gui_push_magnitude, tab="Simulate").input_value() == "55"
    app.editor.on_field_change("robot", "model", "talos")
    assert wait_for(lambda: app.push_panel.gui_push_magnitude.value == 150.0, 15)
    del robot


def test_sweep_exports_do_not_pile_up_as_notices(page, app) -> None:
    """Defect 9: each export of a finished sweep is saved at once, with no notice left to
    close (before: a notice with a download link per export, until closed by hand)."""
    panel = app.sweep_panel
    panel._files = {"json": b"{}\n", "csv": b"direction_deg\n", "png": b"\x89PNG"}
    for b in panel.gui_export.values():
        b.disabled = False
    click_through(page, page.get_by_role("tab", name="Sweep", exact=True))
    wait_for(lambda: close_notifications(page), 5)  # (only the exports' notices are counted)
    for kind in ("JSON", "CSV", "PNG"):
        with page.expect_download(timeout=30_000) as info:
            button = page.get_by_role("button", name=f"Export {kind}")
            click_through(page, button)
        assert info.value.suggested_filename == f"envelope.{kind.lower()}"

    def exports_noticed() -> list[str]:
        notices = page.locator(".mantine-Notification-root").all_inner_texts()
        return [n for n in notices if "envelope" in n or "download" in n.lower()]

    # viser says "Received envelope.png" as a file arrives; saved at once, the notice closes
    # by itself (Mantine's autoClose, 4 s): none is left to close
    assert wait_for(lambda: not exports_noticed(), 10), exports_noticed()
