"""Fig. 1a in a frame of its own: the preview's VRP and DCM over time drawn by plotly.js in a
sandboxed iframe of the plots panel, fed by server-sent events from a small HTTP server of ours.

Why not viser's own plots: viser's page applies every message it receives inside its 3-D render
loop (``FrameSynchronizedMessageHandler``), so a plot update waits for the next frame of the 3-D
scene and shows at the one after.  Where WebGL runs in software (headless Chromium, a machine
without a GPU) a frame of the walking robot takes ~200 ms, and a typed Δx reached Fig. 1a after
~400 ms although the server had the new plots after ~40 ms (bench/dashboard.py --latency).  A
sandboxed iframe (scripts allowed, no same-origin) gets an opaque origin, and Chromium gives such
a frame its own renderer process: its main thread does not wait for the 3-D scene's frames.

The frame loads plotly.js (the ``plotly`` package's own bundle) and the event stream from the
host the page came from, on this server's port.  ``python app.py --fig1a panel`` (also the
default behind ``--public-url``, where only the dashboard's port is reachable) draws Fig. 1a with
viser's plots instead (:class:`dcmviz.dashboard.plots.PreviewPlots`).
"""

from __future__ import annotations

import html
import json
import socket
import threading
import time
from functools import cache
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np
import viser

from dcmviz.dashboard.plots import (
    AXES,
    DCM_STROKE,
    GHOST_STROKE,
    VRP_STROKE,
    moved,
    preview_series,
)
from dcmviz.dashboard.preview import PreviewData

MAX_STREAMS = 64  # open event streams at once by default (each is a thread); more get 503
KEEPALIVE_S = 15.0  # an idle stream gets a comment line this often (proxies close silent ones)
DIGITS = 5  # decimals sent (10 µm, 10 µs: far below a pixel)
FRAME_HEIGHT_PX = 560
FIG1A_MODES = ("stream", "panel")  # Fig. 1a in its own frame, or in viser's plots


def next_free_port(host: str, start: int, tries: int = 20) -> int:
    """The first port from ``start`` on that ``host`` can listen on (0: none of ``tries``; then
    the system picks one): the dashboard's port + 1 by default, one more to forward."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    for port in range(start, min(start + tries, 65536)):
        with socket.socket(family, socket.SOCK_STREAM) as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
            return port
    return 0


@cache
def plotly_js() -> bytes:
    """plotly.js as the ``plotly`` package ships it (read once)."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs().encode()


class FigureStream:
    """An HTTP server on ``host:port`` (0: any free port) that serves plotly.js and streams the
    last published figure to every connected frame (``/events``, server-sent events).  A frame
    that connects gets the last figure at once; one that falls behind gets only the newest."""

    def __init__(
        self, host: str = "127.0.0.1", port: int = 0, max_streams: int = MAX_STREAMS
    ) -> None:
        self.max_streams = max_streams
        self._cond = threading.Condition()
        self._payload: bytes | None = None
        self.version = 0
        self.streams = 0
        self._stopped = False
        stream = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def log_message(self, *args) -> None:  # quiet: the dashboard's console is the user's
                pass

            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                path = self.path.split("?", 1)[0]
                if path == "/plotly.min.js":
                    self._send(200, "application/javascript", plotly_js(), cache_s=86400)
                elif path == "/events":
                    stream._serve_events(self)
                else:
                    self._send(404, "text/plain", b"dcmviz Fig. 1a stream: /events, /plotly.min.js")

            def _send(self, code: int, kind: str, body: bytes, cache_s: int = 0) -> None:
                self.send_response(code)
                self.send_header("Content-Type", kind)
                self.send_header("Content-Length", str(len(body)))
                self.send_header("Access-Control-Allow-Origin", "*")
                self.send_header("Cache-Control", f"max-age={cache_s}" if cache_s else "no-cache")
                self.end_headers()
                self.wfile.write(body)

        family = socket.AF_INET6 if ":" in host else socket.AF_INET

        class Server(ThreadingHTTPServer):
            address_family = family
            daemon_threads = True

        self._http = Server((host, port), Handler)
        self.host = host
        self.port = int(self._http.server_address[1])
        self._thread = threading.Thread(
            target=self._http.serve_forever, name="dcmviz-fig1a", daemon=True
        )
        self._thread.start()

    def publish(self, message: dict) -> None:
        """Send ``message`` (JSON) to every connected frame and to every frame that connects."""
        with self._cond:
            self.version += 1
            # when it left (epoch s): the frames' clock is the same machine's (bench/dashboard.py)
            message = {**message, "version": self.version, "published": time.time()}
            self._payload = (
                b"data: " + json.dumps(message, separators=(",", ":")).encode() + b"\n\n"
            )
            self._cond.notify_all()

    def _serve_events(self, handler: BaseHTTPRequestHandler) -> None:
        with self._cond:
            refused = self.streams >= self.max_streams or self._stopped
            self.streams += 0 if refused else 1
        if refused:
            handler.send_error(503, f"at most {self.max_streams} Fig. 1a streams at once")
            return
        try:
            handler.send_response(200)
            handler.send_header("Content-Type", "text/event-stream")
            handler.send_header("Cache-Control", "no-cache")
            handler.send_header("Access-Control-Allow-Origin", "*")
            handler.end_headers()
            handler.close_connection = True
            seen = 0
            while True:
                with self._cond:
                    fresh = self._cond.wait_for(
                        lambda seen=seen: (
                            self._stopped or (self.version != seen and self._payload is not None)
                        ),
                        timeout=KEEPALIVE_S,
                    )
                    if self._stopped:
                        return
                    payload = self._payload if fresh else None
                    seen = self.version if fresh else seen
                handler.wfile.write(payload if payload is not None else b": keepalive\n\n")
                handler.wfile.flush()
        except OSError:  # the frame went away (reload, closed tab)
            return
        finally:
            with self._cond:
                self.streams -= 1

    def stop(self) -> None:
        with self._cond:
            self._stopped = True
            self._cond.notify_all()
        self._http.shutdown()
        self._http.server_close()
        self._thread.join(timeout=5.0)


# The frame's page: plotly.js and the stream from the host the dashboard came from.  A frame
# records when each figure arrived and the first animation frame after it was drawn
# (window.__fig1a, read by bench/dashboard.py and the browser tests).
FRAME_PAGE = """<!doctype html><html><head><meta charset="utf-8"><style>
html, body { margin: 0; font: 12px sans-serif; background: #fff; }
#msg { color: #a33; padding: 8px; }
</style></head><body><div id="fig"></div><div id="msg"></div><script>
// (no mode bar: it lay over the legend; drag zooms, a double click resets)
const W = window.__fig1a = { received: [], drawn: [], figure: null, error: null };
const here = new URL(document.baseURI);
const host = here.hostname.includes(':') ? '[' + here.hostname + ']' : here.hostname;
const base = 'http://' + host + ':__PORT__';
const say = (text) => { W.error = text; document.getElementById('msg').textContent = text; };
const now = () => performance.timeOrigin + performance.now();
const script = document.createElement('script');
script.src = base + '/plotly.min.js';
script.onerror = () => say('Fig. 1a is streamed from ' + base + ', which this browser cannot ' +
  'reach: open that port too (e.g. ssh -L __PORT__:localhost:__PORT__), or start the dashboard ' +
  'with --fig1a panel.');
script.onload = () => {
  const div = document.getElementById('fig');
  let pending = null, drawing = false;
  const draw = () => {
    if (drawing || pending === null) return;
    const m = pending; pending = null; drawing = true;
    const start = now();
    Plotly.react(div, m.figure.data, m.figure.layout,
                 { displaylogo: false, displayModeBar: false, responsive: true }).then(() => {
      const reacted = now();
      W.figure = m.figure; W.version = m.version;
      requestAnimationFrame(() => {
        W.drawn.push([m.version, now(), m.published * 1e3, start, reacted]);
        drawing = false; draw();
      });
    });
  };
  const events = new EventSource(base + '/events');
  events.onopen = () => { if (W.error) say(''); };
  events.onerror = () => say('Fig. 1a: the stream from ' + base + ' broke off; reconnecting…');
  events.onmessage = (e) => {
    const at = now();
    pending = JSON.parse(e.data); W.received.push([pending.version, at]);
    draw();
  };
};
document.head.appendChild(script);
</script></body></html>"""


def frame_html(port: int, height_px: int = FRAME_HEIGHT_PX) -> str:
    """The plots panel's element: a sandboxed iframe (scripts, no same-origin: its own process)."""
    page = html.escape(FRAME_PAGE.replace("__PORT__", str(int(port))), quote=True)
    return (
        f'<iframe title="Fig. 1a" sandbox="allow-scripts" srcdoc="{page}" '
        f'style="width:100%;height:{height_px}px;border:0;display:block"></iframe>'
    )


def _trace(name: str, axis: str, row: int, color: str, dash: str, x: list, y: np.ndarray) -> dict:
    return {
        "type": "scatter",
        "mode": "lines",
        "name": name,
        "legendgroup": name,
        "showlegend": row == 1,
        "line": {"color": color, "width": 2, "dash": dash},
        "xaxis": "x",
        "yaxis": "y" if row == 1 else f"y{row}",
        "hovertemplate": f"{name} {axis}: %{{y:.3f}} m<extra></extra>",
        "x": x,
        "y": np.round(y, DIGITS).tolist(),
    }


@cache
def _layout() -> dict:
    """Three stacked axes (x, y, z of the preview) on one shared time axis."""
    gap = 0.06
    height = (1.0 - 2 * gap) / 3
    layout: dict = {
        "height": FRAME_HEIGHT_PX - 10,
        "margin": {"l": 52, "r": 8, "t": 8, "b": 36},
        "hovermode": "x unified",
        "uirevision": "fig1a",  # a zoom or pan stays through the updates
        "legend": {"orientation": "h", "x": 0, "y": 1.0, "yanchor": "bottom", "font": {"size": 11}},
        "xaxis": {"title": {"text": "t [s]"}, "anchor": "y3", "zeroline": False},
        "plot_bgcolor": "#fff",
        "paper_bgcolor": "#fff",
        "font": {"size": 11},
    }
    for row, axis in enumerate(AXES, start=1):
        top = 1.0 - (row - 1) * (height + gap)
        layout["yaxis" if row == 1 else f"yaxis{row}"] = {
            "domain": [max(0.0, top - height), top],
            "title": {"text": f"{axis} [m]"},
            "gridcolor": "#eee",
            "zeroline": False,
        }
    layout["xaxis"]["gridcolor"] = "#eee"
    return layout


class PreviewFigure:
    """Fig. 1a streamed to its frame (:class:`FigureStream`): VRP v(t) and DCM ξ(t) of the preview
    on x, y and z, eqs. (13), (16), and those of the kept preview A (grey, dashed).  The same
    interface as :class:`dcmviz.dashboard.plots.PreviewPlots` (``draw``, ``set_ghost``)."""

    def __init__(self, gui: viser.GuiApi, stream: FigureStream) -> None:
        self.stream = stream
        self.handle = gui.add_html(frame_html(stream.port))
        self.ghost: PreviewData | None = None
        self._data: PreviewData | None = None
        self._sent: tuple[np.ndarray, ...] | None = None
        self.figure: dict | None = None  # the last figure published

    def set_ghost(self, ghost: PreviewData | None) -> None:
        """Compare against ``ghost`` (None: no comparison) from the next draw on."""
        self.ghost = ghost
        if self._data is not None:
            self.draw(self._data, force=True)

    def draw(self, data: PreviewData, force: bool = False) -> None:
        """Publish the figure of ``data`` unless no sample moved by more than PLOT_TOLERANCE
        (far below a pixel: a touchdown moves the walked plan by ~1 mm)."""
        self._data = data
        t, axes = preview_series(data, self.ghost)
        columns = (t, *(c for series in axes for c in series))
        if not force and self._sent is not None and not moved(self._sent, columns):
            return
        self._sent = columns
        x = np.round(t, DIGITS).tolist()
        traces = []
        for row, (axis, (v, xi, *kept)) in enumerate(zip(AXES, axes, strict=True), start=1):
            traces.append(_trace("v (VRP)", axis, row, VRP_STROKE, "solid", x, v))
            traces.append(_trace("ξ (DCM)", axis, row, DCM_STROKE, "solid", x, xi))
            if kept:
                traces.append(_trace("A: v", axis, row, GHOST_STROKE, "dot", x, kept[0]))
                traces.append(_trace("A: ξ", axis, row, GHOST_STROKE, "dash", x, kept[1]))
        self.figure = {"data": traces, "layout": _layout()}
        self.stream.publish({"figure": self.figure})
