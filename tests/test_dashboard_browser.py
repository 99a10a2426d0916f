"""End-to-end: the dashboard in a real headless Chromium (Debian ``chromium`` + Playwright).

One server (point-mass backend, for speed) and one browser for the whole module.  Screenshots
go to ``$DCMVIZ_SCREENSHOTS`` (default: a pytest tmp dir).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.browser

viser = pytest.importorskip("viser")
sync_api = pytest.importorskip("playwright.sync_api")

from helpers import free_port, wait_for  # noqa: E402

from dcmviz.config import Config, dumps_preset, load_preset, loads_preset  # noqa: E402
from dcmviz.dashboard import Dashboard  # noqa: E402
from dcmviz.dashboard.headless import CHROMIUM, launch_chromium  # noqa: E402

PRESETS = Path(__file__).resolve().parents[1] / "presets"

if not os.path.exists(CHROMIUM):
    pytest.skip("Debian chromium is not installed", allow_module_level=True)


@pytest.fixture(scope="module")
def app() -> Iterator[tuple[Dashboard, str]]:
    port = free_port()
    server = viser.ViserServer(host="127.0.0.1", port=port, verbose=False)
    config = Config().replace(sim={"backend": "lip"})
    dashboard = Dashboard(server, config, presets_dir=PRESETS)
    yield dashboard, f"http://127.0.0.1:{server.get_port()}"
    dashboard.stop()
    server.stop()


@pytest.fixture(scope="module")
def browser() -> Iterator:
    with sync_api.sync_playwright() as p:
        b = launch_chromium(p)
        yield b
        b.close()


@pytest.fixture(scope="module")
def page(browser, app):
    dashboard, url = app
    page = browser.new_page(viewport={"width": 1200, "height": 760}, accept_downloads=True)
    page.goto(url)
    page.get_by_text("T_ss [s]").wait_for(timeout=30_000)
    # the tab is connected once it reported its camera (the view the tests project into)
    assert wait_for(
        lambda: any(c.camera.image_width > 0 for c in dashboard.server.get_clients().values()), 30
    )
    yield page
    page.close()


def close_notifications(page) -> bool:
    """Close the pop-ups shown (they close themselves too); True if none is left."""
    for button in page.locator("button.mantine-Notification-closeButton").all():
        try:
            button.click(timeout=2000)
        except sync_api.Error:
            pass  # closed by itself meanwhile
    return page.locator(".mantine-Notification-root").count() == 0


def click_through(page, locator, timeout: float = 30.0, **click) -> None:
    """Click ``locator``, closing the pop-ups that may lie over it first (they come and go:
    a robot change, headless Chromium's "software WebGL" notice), until a click lands."""
    import time

    deadline = time.monotonic() + timeout
    while True:
        close_notifications(page)
        try:
            # no wait after the click: nothing in the page navigates, and a click that landed
            # but timed out waiting for "scheduled navigations" (a starved page) was clicked
            # again: a toggle such as Play/Pause toggled back
            locator.click(timeout=15_000, **{"no_wait_after": True, **click})
            return
        except sync_api.Error:
            if time.monotonic() > deadline:
                raise


def number_input(page, dashboard: Dashboard, key: tuple[str, str]):
    """The number box next to a slider (the slider root carries the handle's uuid)."""
    handle = (
        dashboard.push_panel.handles[key[1]]
        if key[0] == "push"
        else dashboard.controls.handles[key]
    )
    uuid = handle._impl.uuid
    box = (
        page.locator(f"[id='{uuid}']").locator("xpath=..").locator("input:not([type=hidden])").first
    )
    # on the panel's tab that holds it, whichever tab an earlier test left open (pop-ups, such as
    # headless Chromium's "software WebGL" notice, closed: they may lie over the tabs)
    if not box.is_visible():
        close_notifications(page)
        page.get_by_role("tab", name="Simulate" if key[0] == "push" else "Plan", exact=True).click()
    box.wait_for(state="visible", timeout=10_000)
    return box


def pixels(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)


def canvas_opacity(page) -> float:
    return float(page.evaluate("getComputedStyle(document.querySelector('canvas')).opacity"))


def test_first_view_is_solid_and_says_how_to_push(page, app, shots: Path) -> None:
    """Issue 14, the first minute: the scene is drawn at full opacity (no environment map whose
    loading fades the canvas), the first tab says what a click on the robot does."""
    dashboard, _ = app
    assert wait_for(lambda: canvas_opacity(page) == 1.0)
    hint = page.get_by_text("Click the robot to push it").first
    hint.wait_for(timeout=15_000)
    assert f"{dashboard.push_panel.gui_push_magnitude.value:.0f} N" in hint.inner_text()
    page.get_by_text("Feasible (the walked plan)").first.wait_for(timeout=15_000)


def test_slider_changes_preview(page, app, shots: Path) -> None:
    dashboard, _ = app
    page.screenshot(path=shots / "01_loaded.png")
    version = dashboard.version
    box = number_input(page, dashboard, ("gait", "n_steps"))
    box.fill("14")
    box.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.n_steps == 14)
    assert dashboard.preview.wait(version + 1)
    assert len([s for s in dashboard.preview.data.soles if s.index >= 0]) == 14
    loaded = pixels(shots / "01_loaded.png")

    def redrawn() -> bool:  # the footsteps and preview redrawn in the page
        page.screenshot(path=shots / "02_n_steps_14.png")
        diff = np.abs(loaded - pixels(shots / "02_n_steps_14.png"))
        return (diff.sum(axis=2) > 30).mean() > 0.001

    assert wait_for(redrawn)


def test_typed_value_beyond_the_robot_is_clamped_and_told(page, app, shots: Path) -> None:
    """The w slider ends at Talos's smallest step width (0.14 m): 0.06 typed is clamped to it
    and the page says so (issue 14: slider ranges are exactly what validation accepts)."""
    dashboard, _ = app
    box = number_input(page, dashboard, ("gait", "step_width"))
    box.fill("0.06")
    box.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.step_width == 0.14)
    page.get_by_text("w [m] = 0.06 is not allowed here: set to 0.14").first.wait_for(timeout=15_000)
    assert wait_for(lambda: box.input_value() == "0.14")
    box.fill("0.17")
    box.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.step_width == 0.17)


def test_bad_combination_reverts(page, app, shots: Path) -> None:
    """Δx at the reach limit is allowed; turning as well would put the steps beyond it.  Issue
    25: the turn slider's range is what validation accepts with Δx = 0.45 m (no turn at all),
    so the typed 0.3 is clamped to it and the page says so; the config never changes."""
    dashboard, _ = app
    length = number_input(page, dashboard, ("gait", "step_length"))
    length.fill("0.45")
    length.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.step_length == 0.45)
    turn_handle = dashboard.controls.handles[("gait", "turn")]
    assert wait_for(lambda: (turn_handle.min, turn_handle.max) == (0.0, 0.0))
    before = dashboard.config
    turn = number_input(page, dashboard, ("gait", "turn"))
    turn.fill("0.3")
    turn.press("Enter")
    page.get_by_text("Δψ [rad] = 0.3 is not allowed here: set to 0").first.wait_for(timeout=10_000)
    assert dashboard.config == before
    assert wait_for(lambda: turn.input_value() == "0")
    page.screenshot(path=shots / "03_invalid_value.png")
    length.fill("0.2")
    length.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.step_length == 0.2)
    assert wait_for(lambda: turn_handle.max > 0.3)  # the turn may turn again


def test_feasibility_warning_in_the_page(page, app, shots: Path) -> None:
    """Issue 9: a T_start the checker warns about (the D2 waypoint leaves the support polygon)
    shows its warning beside the preview and in the status, and marks the waypoint."""
    dashboard, _ = app
    box = number_input(page, dashboard, ("gait", "t_start"))
    box.fill("0.2")
    box.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.t_start == 0.2)
    page.get_by_text("VRP waypoint 2 (D2").first.wait_for(timeout=10_000)
    page.get_by_text("feasibility warning", exact=False).first.wait_for(timeout=15_000)
    assert wait_for(lambda: any(w.waypoint == 1 for w in dashboard.preview.warnings))
    page.screenshot(path=shots / "03b_feasibility_warning.png")
    box.fill("1")
    box.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.t_start == 1.0)
    page.get_by_text("Feasible (the walked plan)").first.wait_for(timeout=10_000)


def test_push_raises_and_recovers_dcm_error(page, app, shots: Path) -> None:
    dashboard, _ = app
    page.get_by_role("tab", name="Simulate").click()
    resets = dashboard.loop.resets
    page.get_by_role("button", name="Reset").click()  # a fresh walk: no plan-end loop inside
    assert wait_for(lambda: dashboard.loop.resets == resets + 1, timeout=15)
    assert wait_for(lambda: dashboard.loop.session.t > 1.2, timeout=15)
    falls = dashboard.loop.falls
    magnitude = number_input(page, dashboard, ("push", "magnitude"))
    n_notes = len(dashboard.notifications)
    magnitude.fill("80")
    magnitude.press("Enter")
    assert wait_for(lambda: dashboard.push_panel.gui_push_magnitude.value == 80.0)
    assert "80 N" in dashboard.push_panel.hint()
    # "80" is 80.0, not a changed value: no notification (the guard only tells real clamps)
    assert not any(t == "Value changed" for t, _ in list(dashboard.notifications)[n_notes:])
    session = dashboard.loop.session
    n_pushes = len(session.pushes)
    page.get_by_role("button", name="Push", exact=True).click()
    assert wait_for(lambda: len(session.pushes) == n_pushes + 1, timeout=15)
    t_push = session.pushes[-1].start
    assert wait_for(lambda: session.t > t_push + 0.3, timeout=10)
    page.screenshot(path=shots / "04_push.png")
    assert wait_for(lambda: session.t > t_push + 3.0)
    history = session.history()
    t, error = history["t"], history["dcm_error"]
    before = error[(t > t_push - 0.5) & (t < t_push)]
    after = error[(t >= t_push) & (t < t_push + 3.0)]
    peak = after.max()
    assert peak > max(0.01, 3 * before.max())  # the push shows in the DCM error ...
    assert after[-1] < 0.3 * peak  # ... and the walker recovers
    assert dashboard.loop.falls == falls


def test_second_tab_sees_same_session(browser, page, app) -> None:
    dashboard, url = app
    first = number_input(page, dashboard, ("gait", "n_steps"))
    first.fill("13")  # a state the first tab sets (this test's own, whatever ran before)
    first.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.n_steps == 13)
    other = browser.new_page(viewport={"width": 900, "height": 600})
    other.goto(url)
    other.get_by_text("T_ss [s]").wait_for(timeout=30_000)
    box = number_input(other, dashboard, ("gait", "n_steps"))
    assert box.input_value() == "13"  # the state the first tab set
    box.fill("12")
    box.press("Enter")
    assert wait_for(lambda: dashboard.config.gait.n_steps == 12)
    assert wait_for(
        lambda: number_input(page, dashboard, ("gait", "n_steps")).input_value() == "12"
    )
    other.close()
    t = dashboard.loop.session.t
    assert wait_for(lambda: dashboard.loop.session.t > t + 0.3)  # still running for the others


def field(container, label: str):
    """The text box of a viser control labelled ``label`` (exactly) inside ``container``."""
    import re

    row = container.locator(".mantine-Flex-root").filter(
        has=container.page.locator("label", has_text=re.compile(f"^{re.escape(label)}$"))
    )
    return row.locator("input, textarea").first


def test_export_asks_a_name_and_says_what_changed(page, app, shots: Path) -> None:
    """Issue 25: an export after an edit does not keep the old name and a description that no
    longer matches: it asks for a file name, a name and a description, suggested from what
    changed since the preset was loaded; what downloads loads back as the dashboard's config,
    named so."""
    dashboard, _ = app
    g1 = load_preset(PRESETS / "g1_walk.toml").replace(sim={"backend": "lip"})  # (software GL)
    assert dashboard.preset_panel.on_upload("g1_lip.toml", dumps_preset(g1).encode(), None)
    assert wait_for(lambda: dashboard.config.robot.model == "g1")
    loaded = dashboard.config
    new_length = round(loaded.gait.step_length + 0.02, 2)
    assert dashboard.editor.on_field_change("gait", "step_length", new_length)
    click_through(page, page.get_by_role("tab", name="Presets"))  # ("Push reset" for the G1)
    click_through(page, page.get_by_role("button", name="Export preset…"))
    dialog = page.get_by_role("dialog")
    dialog.wait_for(timeout=10_000)
    changed = f"gait.step_length {loaded.gait.step_length:g} → {new_length:g}"
    dialog.get_by_text(changed).first.wait_for(timeout=15_000)
    boxes = dialog.locator("input, textarea")
    values = [boxes.nth(i).input_value() for i in range(boxes.count())]
    assert f"{loaded.name} (edited)" in values  # the suggested name
    assert any(changed in v for v in values), values  # the suggested description
    field(dialog, "file name").fill("my_g1_walk")
    field(dialog, "description").fill("G1, a little longer steps")
    page.screenshot(path=shots / "05_export_dialog.png")
    with page.expect_download(timeout=10_000) as info:
        dialog.get_by_role("button", name="Download").click()
    assert info.value.suggested_filename == "my_g1_walk.toml"
    config = loads_preset(Path(info.value.path()).read_text())
    assert config.name == f"{loaded.name} (edited)"
    assert config.description == "G1, a little longer steps"
    assert config.gait.step_length == new_length
    assert wait_for(lambda: dashboard.config == config)  # the dashboard's config is named so
    assert wait_for(lambda: page.get_by_role("dialog").count() == 0)
    page.screenshot(path=shots / "05_presets.png")
    talos = load_preset(PRESETS / "walk_forward.toml").replace(sim={"backend": "lip"})
    assert dashboard.preset_panel.on_upload("talos_lip.toml", dumps_preset(talos).encode(), None)
    assert wait_for(lambda: dashboard.config.robot.model == "talos")


def test_upload_preset(page, app, shots: Path) -> None:
    dashboard, _ = app
    page.get_by_role("tab", name="Presets").click()
    before = dashboard.config
    upload = page.locator("input[type=file]").first
    upload.set_input_files(
        files=[{"name": "bad.toml", "mimeType": "text/plain", "buffer": b"[gait]\nt_ss = -1.0\n"}]
    )
    assert wait_for(
        lambda: dashboard.notifications and dashboard.notifications[-1][0] == "Preset refused"
    )
    assert dashboard.config == before
    # refused by the size the browser declares, before viser stores any of it
    for name, content, why in (("big.toml", b"#" * 5_000_000, "5000000 bytes"),
                               ("empty.toml", b"", "empty")):  # fmt: skip
        n = len(dashboard.notifications)
        upload.set_input_files(files=[{"name": name, "mimeType": "text/plain", "buffer": content}])
        assert wait_for(lambda n=n: len(dashboard.notifications) > n)
        title, body = dashboard.notifications[-1]
        assert title == "Upload refused" and why in body and "docs/presets.md" in body
        assert dashboard.server.gui._current_file_upload_states == {}
        assert dashboard.config == before
    good = before.replace(gait={"n_steps": 6}).model_copy(update={"name": "Uploaded"})
    from dcmviz.config import dumps_preset

    upload.set_input_files(
        files=[
            {"name": "good.toml", "mimeType": "text/plain", "buffer": dumps_preset(good).encode()}
        ]
    )
    assert wait_for(lambda: dashboard.config.name == "Uploaded")
    assert dashboard.config == good
    page.screenshot(path=shots / "06_uploaded.png")


def aim_camera_at(dashboard: Dashboard, client, page, point, timeout: float = 20.0):
    """Put ``client``'s camera behind-left of ``point`` (view ≈ +x, the point left of the
    panel) and return the point's pixel in the page once the tab has applied that camera."""
    point = np.asarray(point, float)
    position = point + np.array([-2.0, -0.6, 0.4])
    look_at = point + np.array([0.0, -0.5, 0.0])
    # through the view, as Frame robot does: camera follow (on by default) keeps this camera
    # (set on client.camera alone, a late report of the follow's last camera from the tab
    # could reach the server first and the follow put the tab back at its old offset)
    dashboard.view.put_camera(client, position, look_at)
    canvas = page.locator("canvas").first

    def camera_applied() -> bool:
        # the tab applied the camera once it reports it back (position, look-at, an orientation
        # along them) for the canvas as it is now: the tab reports its camera when the camera
        # moves, so a report can carry the canvas's shape from before the plots panel narrowed
        # it (1200 × 760 px for 796 × 760: the projection 40 px off when this test ran alone).
        # Its shape, not its size: viser lowers the canvas's resolution while frames are slow
        cam, box = client.camera, canvas.bounding_box()
        return bool(
            np.allclose(cam.position, position, atol=1e-3)
            and np.allclose(cam.look_at, look_at, atol=1e-3)
            and looks_along(cam, look_at - position)
            and box is not None
            and abs(cam.image_width / cam.image_height - box["width"] / box["height"]) < 0.01
        )

    assert wait_for(camera_applied, timeout)
    u, v = project(client.camera, point)
    box = canvas.bounding_box()
    return box["x"] + u * box["width"], box["y"] + v * box["height"]


def test_click_on_the_robot_pushes_it(page, app, shots: Path, request) -> None:
    """Clicking the point mass (a clickable sphere at the CoM) pushes along the view direction;
    one click, one push, and the status names the force it applied.  Every wait is on its
    condition: the camera the tab reports, the sphere drawn where it projects, no pop-up over it.
    Before the click the tab shows its aim arrow (its own view direction, the panel's |F|), and
    the click applies exactly that force."""
    dashboard, _ = app
    dashboard.push_panel.gui_push_magnitude.value = 100.0  # its own, whatever ran before
    dashboard.sim_panel.on_play(False)
    # the module's later tests need the walk going, whether this one passes or fails (a failure
    # below left it paused: the k_ξ drag test then waited 15 s for a walk that never moved)
    request.addfinalizer(lambda: dashboard.sim_panel.on_play(True))
    assert wait_for(lambda: not dashboard.loop.snapshot.status.playing)
    client = list(dashboard.server.get_clients().values())[-1]
    com = np.asarray(dashboard.loop.snapshot.com)
    x, y = aim_camera_at(dashboard, client, page, com)
    box = page.locator("canvas").first.bounding_box()
    assert wait_for(lambda: close_notifications(page), timeout=15)  # none over the robot
    clip = {"x": x - 12, "y": y - 12, "width": 24, "height": 24}

    def sphere_drawn() -> bool:  # the grey sphere under the pointer, two frames alike
        a, b = pixels_of(page, clip), pixels_of(page, clip)
        dark = b.mean(axis=2) < 190  # the sphere, not the white floor and its grid lines
        return bool(np.array_equal(a, b) and dark.mean() > 0.3)

    assert wait_for(sphere_drawn, timeout=15)
    # the tab's aim arrow: its own horizontal view direction (from the camera set above) and the
    # panel's magnitude, drawn in the tab before the click
    view = np.asarray(client.camera.look_at) - np.asarray(client.camera.position)
    view[2] = 0.0
    view /= np.linalg.norm(view)
    magnitude = dashboard.push_panel.gui_push_magnitude.value

    def aimed() -> bool:
        shown = dashboard.aim.shown(client.client_id)
        return (
            shown is not None
            and float(shown[0] @ view) > np.cos(np.radians(2.0))
            and shown[1] == magnitude
        )

    assert wait_for(aimed)
    direction, shown_magnitude, label = dashboard.aim.shown(client.client_id)
    assert shown_magnitude == magnitude and f"{magnitude:.0f} N" in label
    # and the tab draws it: orange where the arrow's middle projects
    tail, head = dashboard.aim.world_points(client.client_id)
    ax, ay = project(client.camera, tail + 0.7 * (head - tail))  # well inside the view
    arrow_clip = {"x": box["x"] + ax * box["width"] - 4, "y": box["y"] + ay * box["height"] - 4,
                  "width": 8, "height": 8}  # fmt: skip

    def orange() -> bool:  # lit, the orange arrow shades from orange to gold: warm, not grey
        r, g, b = pixels_of(page, arrow_clip).reshape(-1, 3).T
        return bool(((r > 180) & (g > 40) & (b < 0.75 * g) & (r - b > 80)).any())

    assert wait_for(orange, timeout=15)
    n, clicks = len(dashboard.loop.session.pushes), dashboard.push_panel.clicks
    page.mouse.click(x, y)
    assert wait_for(lambda: len(dashboard.loop.session.pushes) == n + 1, timeout=15)
    assert dashboard.push_panel.clicks == clicks + 1
    push = dashboard.loop.session.pushes[-1]
    assert push.body == "torso"
    # exactly the force the arrow showed: the view's horizontal direction times |F|
    np.testing.assert_allclose(push.force, magnitude * view, atol=1e-6 * magnitude)
    dashboard.sim_panel.on_play(True)
    page.get_by_text("pushed torso").first.wait_for(timeout=15_000)  # the status names it
    page.screenshot(path=shots / "07_click_push.png")


def looks_along(cam, direction: np.ndarray, tol: float = 1e-3) -> bool:
    """Whether the camera's reported orientation (its OpenCV z axis) points along ``direction``."""
    import viser.transforms as vtf

    z = vtf.SO3(np.asarray(cam.wxyz)).as_matrix()[:, 2]
    return bool(np.linalg.norm(z - direction / np.linalg.norm(direction)) < tol)


def project(cam, point: np.ndarray) -> tuple[float, float]:
    """Where ``point`` appears in the canvas, as fractions of its width and height (pinhole
    projection; viser cameras are OpenCV-style: x right, y down, z forward)."""
    import viser.transforms as vtf

    R = vtf.SO3(np.asarray(cam.wxyz)).as_matrix()
    p = R.T @ (np.asarray(point) - np.asarray(cam.position))
    f = 0.5 * cam.image_height / np.tan(0.5 * cam.fov)
    u = (0.5 * cam.image_width + f * p[0] / p[2]) / cam.image_width
    v = (0.5 * cam.image_height + f * p[1] / p[2]) / cam.image_height
    return float(u), float(v)


def pixels_of(page, clip: dict) -> np.ndarray:
    from io import BytesIO

    from PIL import Image

    png = page.screenshot(clip=clip, type="png")
    return np.asarray(Image.open(BytesIO(png)).convert("RGB"), dtype=np.int16)


def test_dragging_k_xi_changes_tracking_without_restart(page, app, shots: Path) -> None:
    """Issue 8: drag the k_ξ slider while the robot walks.  Every tick during and after the drag
    is recorded on the simulation thread with the gain in effect: the walk's clock never goes
    back (no restart), the session's k_ξ is the dragged value, and each command obeys eq. (41),
    v_cmd = v_ref + (1 + k_ξ b)(ξ − ξ_adj), with the gain of its tick, not the old one."""
    dashboard, _ = app
    loop = dashboard.loop
    dashboard.sim_panel.on_play(True)  # while the robot walks (whatever ran before)
    assert dashboard.editor.on_field_change("gait", "mode", "continuous")  # never loops back
    assert wait_for(lambda: loop.session.config.gait.mode == "continuous", timeout=10)
    session = loop.session
    assert wait_for(lambda: session.t > 1.5, timeout=15)  # walking
    k_before = session.config.control.k_xi
    ticks: list = []
    unsubscribe = session.subscribe(
        lambda tick: ticks.append((tick, session.config.control.k_xi, session.config.dcm.b))
    )
    try:
        page.get_by_role("tab", name="Plan").click()
        handle = dashboard.controls.handles[("control", "k_xi")]
        thumb = page.locator(f"[id='{handle._impl.uuid}']").locator("[role=slider]").first
        thumb.scroll_into_view_if_needed()
        track = page.locator(f"[id='{handle._impl.uuid}']").bounding_box()
        box = thumb.bounding_box()
        x0, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        target = 8.0
        x1 = track["x"] + track["width"] * (target - handle.min) / (handle.max - handle.min)
        n_notes = loop.note_seq
        page.mouse.move(x0, y)
        page.mouse.down()
        page.mouse.move(x1, y, steps=12)  # a drag: a stream of values
        page.mouse.up()
        assert wait_for(lambda: loop.note_seq > n_notes and handle.value > k_before + 2.0)
        k_after = handle.value
        assert wait_for(lambda: session.config.control.k_xi == k_after)
        assert dashboard.config.control.k_xi == k_after
        page.get_by_text("gains changed (walk continues)").first.wait_for(timeout=15_000)
        page.screenshot(path=shots / "08_k_xi_dragged.png")
        # a lateral push moves ξ away from ξ_adj, so eq. (41) with the new gain is tested
        loop.post(
            "push", {"force": (0.0, 40.0, 0.0), "duration": 3.0, "ramp": 0.2, "body": "torso"}
        )

        def with_new_gain() -> list:
            return [
                (tick, k, b) for tick, k, b in list(ticks)
                if k == k_after and np.linalg.norm(tick.command.xi - tick.command.xi_adj) > 1e-5
            ]  # fmt: skip

        assert wait_for(lambda: len(with_new_gain()) >= 50, timeout=15)
    finally:
        unsubscribe()
    assert loop.session is session
    times = np.array([tick.t for tick, _, _ in ticks])
    index = np.array([tick.index for tick, _, _ in ticks])
    assert np.all(np.diff(times) > 0) and np.all(np.diff(index) == 1)  # no reset, none missed
    for tick, k, b in ticks:  # eq. (41) with the gain in effect at that tick
        cmd = tick.command
        np.testing.assert_allclose(
            cmd.v_cmd, cmd.v_ref + (1.0 + k * b) * (cmd.xi - cmd.xi_adj), atol=1e-12
        )
    # tracking changed: with the old gain, the new commands would differ by Δk b (ξ − ξ_adj)
    for tick, _, b in with_new_gain():
        cmd = tick.command
        old = cmd.v_ref + (1.0 + k_before * b) * (cmd.xi - cmd.xi_adj)
        gap = np.linalg.norm(cmd.v_cmd - old)
        assert gap == pytest.approx(
            (k_after - k_before) * b * np.linalg.norm(cmd.xi - cmd.xi_adj), rel=1e-9
        )
    assert dashboard.editor.on_field_change("gait", "mode", "plan")
