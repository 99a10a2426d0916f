"""Fig. 1a in a frame of its own (dcmviz.dashboard.fig1a): the event stream, the figure it
carries against the plan it was drawn from, and the frame in a real headless Chromium."""

from __future__ import annotations

import dataclasses
import http.client
import json
import os
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
import pytest
from helpers import free_port, wait_for

from dcmviz.config import Config, load_preset
from dcmviz.dashboard.fig1a import DIGITS, FigureStream, PreviewFigure, frame_html
from dcmviz.dashboard.plots import PLOT_TOLERANCE, PREVIEW_POINTS
from dcmviz.dashboard.preview import preview_data
from dcmviz.gait import plan_from_config
from dcmviz.robots import load_robot

viser = pytest.importorskip("viser")

PRESETS = Path(__file__).resolve().parents[1] / "presets"


def events(port: int) -> tuple[http.client.HTTPConnection, http.client.HTTPResponse]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.request("GET", "/events")
    return conn, conn.getresponse()


def next_event(response: http.client.HTTPResponse) -> dict:
    """The next ``data:`` line of a server-sent event stream, as JSON (keepalives skipped)."""
    while True:
        line = response.readline()
        assert line, "the stream ended"
        if line.startswith(b"data: "):
            return json.loads(line[6:])


@pytest.fixture
def stream() -> Iterator[FigureStream]:
    s = FigureStream("127.0.0.1", 0, max_streams=2)
    yield s
    s.stop()


def test_a_frame_gets_the_last_figure_at_once_and_every_one_after(stream) -> None:
    stream.publish({"figure": {"n": 1}})
    stream.publish({"figure": {"n": 2}})
    conn, response = events(stream.port)
    assert response.status == 200
    assert response.getheader("Content-Type") == "text/event-stream"
    assert response.getheader("Access-Control-Allow-Origin") == "*"  # the sandboxed frame: null
    first = next_event(response)
    assert first["figure"] == {"n": 2} and first["version"] == 2  # the newest only
    stream.publish({"figure": {"n": 3}})
    assert next_event(response)["figure"] == {"n": 3}
    # a second frame connecting now starts at the newest as well
    conn2, response2 = events(stream.port)
    assert next_event(response2)["version"] == 3
    assert wait_for(lambda: stream.streams == 2, 5)
    # a third is refused (max_streams = 2) with a status the frame reports
    conn3, response3 = events(stream.port)
    assert response3.status == 503 and b"at most 2" in response3.read()
    conn3.close()
    conn2.close()
    stream.stop()  # the open stream ends (not hangs) when the dashboard stops
    assert response.read().strip() == b""  # EOF, not a timeout
    conn.close()
    assert wait_for(lambda: stream.streams == 0, 5)


def test_the_stream_serves_plotly_js_and_nothing_else(stream) -> None:
    conn = http.client.HTTPConnection("127.0.0.1", stream.port, timeout=10)
    conn.request("GET", "/plotly.min.js")
    response = conn.getresponse()
    body = response.read()
    assert response.status == 200 and response.getheader("Content-Type") == "application/javascript"
    assert len(body) > 1_000_000 and b"Plotly" in body[:5000]
    conn.request("GET", "/../etc/passwd")
    response = conn.getresponse()
    assert response.status == 404 and b"/events" in response.read()
    conn.close()


def _figure_of(stream: FigureStream) -> dict:
    conn, response = events(stream.port)
    try:
        return next_event(response)["figure"]
    finally:
        conn.close()


def _trace(figure: dict, name: str, row: int) -> tuple[np.ndarray, np.ndarray]:
    axis = "y" if row == 1 else f"y{row}"
    (trace,) = [t for t in figure["data"] if t["name"] == name and t["yaxis"] == axis]
    return np.asarray(trace["x"]), np.asarray(trace["y"])


def test_the_figure_is_the_plans_preview_and_A_on_its_times(stream) -> None:
    """The streamed traces against the plan: the sampled VRP and DCM (to the digits sent), the
    walk ending at rest between its last two footsteps (the terminal constraint, §II-C: an
    independent fact), A's traces on B's times, and no message for a change below a pixel."""
    config = load_preset(PRESETS / "walk_forward.toml")
    robot = load_robot(config.robot.model)
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        figure = PreviewFigure(server.gui, stream)
        plan = plan_from_config(config)
        data = preview_data(plan, robot.spec)
        figure.draw(data)
        sent = _figure_of(stream)
        assert sent == json.loads(json.dumps(figure.figure))
        t, xi_x = _trace(sent, "ξ (DCM)", 1)
        assert len(t) <= PREVIEW_POINTS + 1 and t[-1] == pytest.approx(data.t[-1], abs=10**-DIGITS)
        for row in (1, 2, 3):
            _, v = _trace(sent, "v (VRP)", row)
            _, xi = _trace(sent, "ξ (DCM)", row)
            at = np.searchsorted(data.t, t - 1e-9)
            np.testing.assert_allclose(v, data.vrp[at, row - 1], atol=10**-DIGITS)
            np.testing.assert_allclose(xi, data.dcm[at, row - 1], atol=10**-DIGITS)
        last_two = np.array([s.position for s in plan.steps[-2:]])
        assert xi_x[-1] == pytest.approx(last_two[:, 0].mean(), abs=1e-3)
        assert not any(tr["name"].startswith("A:") for tr in sent["data"])

        # A kept, then B with 2 cm shorter steps: A's traces on B's times are A's own samples
        # wherever A was sampled at those times (same timing: every one of them)
        figure.set_ghost(data)
        plan_b = plan_from_config(
            config.replace(gait={"step_length": config.gait.step_length - 0.02})
        )
        data_b = preview_data(plan_b, robot.spec)
        np.testing.assert_array_equal(data_b.t, data.t)
        figure.draw(data_b)
        sent = _figure_of(stream)
        for row in (1, 2, 3):
            _, ghost = _trace(sent, "A: ξ", row)
            np.testing.assert_allclose(ghost, data.dcm[at, row - 1], atol=10**-DIGITS)
        _, xi_b = _trace(sent, "ξ (DCM)", 1)
        shorter = (len(plan_b.steps) - 2) * 0.02  # the generated steps advance by Δx each
        assert xi_x[-1] - xi_b[-1] == pytest.approx(shorter, abs=0.03)

        # a redraw that moves no sample by more than PLOT_TOLERANCE sends nothing
        version = stream.version
        nudged = dataclasses.replace(data_b, dcm=data_b.dcm + 0.5 * PLOT_TOLERANCE)
        figure.draw(nudged)
        assert stream.version == version
        moved = dataclasses.replace(data_b, dcm=data_b.dcm + 2 * PLOT_TOLERANCE)
        figure.draw(moved)
        assert stream.version == version + 1
    finally:
        server.stop()


def test_a_bad_mode_is_refused_with_the_modes_allowed() -> None:
    from dcmviz.dashboard import Dashboard

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        with pytest.raises(ValueError, match="fig1a: 'svg' is not one of stream, panel"):
            Dashboard(server, Config().replace(sim={"backend": "lip"}), fig1a="svg", start=False)
    finally:
        server.stop()


def test_panel_mode_draws_fig1a_in_viser_plots_without_a_stream() -> None:
    """``--fig1a panel`` (the default behind a TLS proxy): viser's uPlots carry the preview."""
    from dcmviz.dashboard import Dashboard
    from dcmviz.dashboard.plots import PreviewPlots

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    dashboard = Dashboard(
        server, Config().replace(sim={"backend": "lip"}), fig1a="panel", start=False
    )
    try:
        assert dashboard.fig1a_stream is None and isinstance(dashboard.preview_plots, PreviewPlots)
        data = dashboard.preview.data
        t, v, xi = (np.asarray(a) for a in dashboard.preview_plots.handles[0].data[:3])
        np.testing.assert_allclose(xi, np.interp(t, data.t, data.dcm[:, 0]), atol=1e-5)
        end = np.mean([s.position[0] for s in dashboard.preview.plan.steps[-2:]])
        assert xi[-1] == pytest.approx(end, abs=1e-3)
    finally:
        dashboard.stop()
        server.stop()


@pytest.mark.parametrize("where", ["PlanView", "SimView.start"])
def test_a_dashboard_that_fails_to_build_frees_fig1a_s_port(monkeypatch, where) -> None:
    """A construction that raises after Fig. 1a's stream is listening (a panel built after it,
    or a thread that fails to start) stops the stream: its port is free again, no thread
    serves it, and the walk's threads that did start are stopped."""
    import socket

    import dcmviz.dashboard.dashboard as dashboard_module
    from dcmviz.dashboard import Dashboard

    class Broken(Exception):
        pass

    def broken(*args, **kwargs):
        raise Broken(where)

    if where == "PlanView":
        monkeypatch.setattr(dashboard_module, "PlanView", broken)
    else:
        monkeypatch.setattr(dashboard_module.SimView, "start", broken)
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    port = free_port()
    before = set(threading.enumerate())
    try:
        with pytest.raises(Broken):
            Dashboard(
                server, Config().replace(sim={"backend": "lip"}), fig1a="stream", fig1a_port=port
            )
        left = [t.name for t in set(threading.enumerate()) - before if t.is_alive()]
        assert not [name for name in left if name.startswith("dcmviz-")], left
        with socket.socket() as s:  # the stream's port is free
            s.bind(("127.0.0.1", port))
    finally:
        server.stop()


# -- in a real browser ---------------------------------------------------------------------------
from dcmviz.dashboard.headless import CHROMIUM, launch_chromium  # noqa: E402


@pytest.fixture(scope="module")
def browser() -> Iterator:
    if not os.path.exists(CHROMIUM):
        pytest.skip("Debian chromium is not installed")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as p:
        b = launch_chromium(p)
        yield b
        b.close()


def fig1a_frame(page):
    """Fig. 1a's frame in the page, once plotly.js drew a figure in it."""
    frame = page.wait_for_selector('iframe[title="Fig. 1a"]', state="attached", timeout=30_000)
    frame = frame.content_frame()
    frame.wait_for_function("window.__fig1a && window.__fig1a.drawn.length > 0", timeout=60_000)
    return frame


def drawn_trace(frame, name: str, row: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """A trace as plotly.js holds it in the frame (the graph div's data)."""
    axis = "y" if row == 1 else f"y{row}"
    xy = frame.evaluate(
        """([name, axis]) => { const d = document.getElementById('fig').data
             .find((t) => t.name === name && t.yaxis === axis);
           return d ? [d.x, d.y] : null; }""",
        [name, axis],
    )
    assert xy is not None, f"no trace {name} on {axis}"
    return np.asarray(xy[0]), np.asarray(xy[1])


@pytest.mark.browser
def test_fig1a_frame_draws_the_walked_plan_and_follows_a_typed_step_length(browser) -> None:
    """The dashboard's Fig. 1a frame (sandboxed: its own origin and process) draws the walked
    plan; Δx typed in the page redraws it with the new plan; a reloaded tab gets it at once."""
    from dcmviz.dashboard import Dashboard

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    dashboard = Dashboard(server, Config().replace(sim={"backend": "lip"}), presets_dir=PRESETS)
    page = browser.new_page(viewport={"width": 1200, "height": 760})
    try:
        page.goto(f"http://127.0.0.1:{server.get_port()}")
        page.get_by_text("T_ss [s]").wait_for(timeout=30_000)
        assert page.evaluate(
            "document.querySelector('iframe[title=\"Fig. 1a\"]').sandbox.value"
        ) == ("allow-scripts")
        frame = fig1a_frame(page)
        assert frame.evaluate("window.__fig1a.error") is None
        t, xi = drawn_trace(frame, "ξ (DCM)")
        plan = dashboard.preview.plan
        end = np.mean([s.position[0] for s in plan.steps[-2:]])
        assert xi[-1] == pytest.approx(end, abs=1e-3)  # the walk ends at rest between its feet
        data = dashboard.preview.data
        np.testing.assert_allclose(xi, np.interp(t, data.t, data.dcm[:, 0]), atol=1e-4)

        # Δx typed in the page's number box: the frame draws the plan the walk now takes
        uuid = dashboard.controls.handles[("gait", "step_length")]._impl.uuid
        box = page.locator(f"[id='{uuid}']").locator("xpath=..").locator("input:not([type=hidden])")
        length = round(dashboard.config.gait.step_length - 0.03, 3)
        box.first.fill(str(length))
        box.first.press("Enter")
        assert wait_for(lambda: dashboard.config.gait.step_length == length, 15)
        assert wait_for(
            lambda: dashboard.preview.plan is not plan
            and abs(drawn_trace(frame, "ξ (DCM)")[1][-1] - np.mean(
                [s.position[0] for s in dashboard.preview.plan.steps[-2:]])) < 1e-3,
            20,
        )  # fmt: skip
        assert drawn_trace(frame, "ξ (DCM)")[1][-1] < xi[-1] - 0.03  # shorter steps end nearer

        # a reload: the new frame is drawn from the stream's last figure, no change needed
        # (the walk goes on meanwhile and may publish a newer figure: never an older one)
        version = dashboard.fig1a_stream.version
        page.reload()
        frame = fig1a_frame(page)
        assert frame.evaluate("window.__fig1a.drawn[0][0]") >= version
    finally:
        page.close()
        dashboard.stop()
        server.stop()


@pytest.mark.browser
def test_an_unreachable_stream_says_which_port_to_open(browser) -> None:
    """The frame on a page whose host does not serve the stream's port tells what to do."""
    dead = free_port()  # nothing listens there
    body = f"<!doctype html><html><body>{frame_html(dead)}</body></html>".encode()

    class Page(BaseHTTPRequestHandler):
        def log_message(self, *args) -> None:
            pass

        def do_GET(self) -> None:  # noqa: N802
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

    http_server = ThreadingHTTPServer(("127.0.0.1", 0), Page)
    threading.Thread(target=http_server.serve_forever, daemon=True).start()
    page = browser.new_page()
    try:
        page.goto(f"http://127.0.0.1:{http_server.server_address[1]}/")
        frame = page.wait_for_selector('iframe[title="Fig. 1a"]', timeout=15_000).content_frame()
        frame.wait_for_function("window.__fig1a && window.__fig1a.error !== null", timeout=20_000)
        text = frame.inner_text("#msg")
        assert f"http://127.0.0.1:{dead}" in text and "--fig1a panel" in text
    finally:
        page.close()
        http_server.shutdown()
        http_server.server_close()
