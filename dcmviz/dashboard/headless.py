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


def launch_chromium(playwright: Any) -> Any:
    """A headless Chromium browser from a ``sync_playwright()`` context."""
    return playwright.chromium.launch(executable_path=CHROMIUM, args=list(CHROMIUM_ARGS))
