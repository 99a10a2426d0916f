"""Headless Chromium for screenshots, benchmarks and end-to-end tests of the dashboard.

Debian's ``chromium`` package, driven by Playwright (``playwright install`` cannot download
browsers on machines without general network access).  Without the background-networking flags
Chromium keeps trying hosts it cannot reach.
"""

from __future__ import annotations

from typing import Any

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = (
    "--no-sandbox",
    "--headless",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-quic",
    "--no-first-run",
    "--disable-component-update",
    "--disable-sync",
)


# Without ``--disable-gpu`` but with these, Chromium composites the page on the GPU path that
# SwiftShader emulates, as a browser with a GPU does; with ``--disable-gpu`` it composites in
# software and copies every WebGL frame back on the page's main thread (``GLES2::ReadPixels``),
# where the page's own work then waits for it (bench/dashboard.py --gpu-compositing).
GPU_COMPOSITING_ARGS = ("--use-angle=swiftshader", "--enable-unsafe-swiftshader")


def launch_chromium(playwright: Any, gpu_compositing: bool = False) -> Any:
    """A headless Chromium browser from a ``sync_playwright()`` context (software compositing,
    the tests' flags; ``gpu_compositing``: SwiftShader's emulated GPU path, for benches)."""
    args = list(CHROMIUM_ARGS)
    if gpu_compositing:
        args = [a for a in args if a != "--disable-gpu"] + list(GPU_COMPOSITING_ARGS)
    return playwright.chromium.launch(executable_path=CHROMIUM, args=args)
