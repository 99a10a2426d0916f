"""A demo for a room in a real headless Chromium (issue 26): the presenter's page opened with the
presenter URL on 127.0.0.1, a watcher's page opened with the watch URL from a second loopback
address (127.0.0.2: to the server, another machine)."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

pytestmark = pytest.mark.browser

viser = pytest.importorskip("viser")
sync_api = pytest.importorskip("playwright.sync_api")

from helpers import free_port, wait_for  # noqa: E402

from dcmviz.config import Config  # noqa: E402
from dcmviz.dashboard import Dashboard  # noqa: E402
from dcmviz.dashboard.audience import PRESENTER, WATCHER, presenter_url, watch_url  # noqa: E402
from dcmviz.dashboard.headless import CHROMIUM, launch_chromium  # noqa: E402

if not os.path.exists(CHROMIUM):
    pytest.skip("Debian chromium is not installed", allow_module_level=True)

KEY = "room-demo-key-42"


@pytest.fixture(scope="module")
def room() -> Iterator[tuple[Dashboard, int]]:
    port = free_port()
    server = viser.ViserServer(host="0.0.0.0", port=port, verbose=False)
    config = Config().replace(sim={"backend": "lip"}, gait={"mode": "continuous"})
    dashboard = Dashboard(server, config, key=KEY)
    yield dashboard, port
    dashboard.stop()
    server.stop()


def n_box(page, dashboard: Dashboard):
    """The number box of the footstep count n (next to its slider; the root carries the uuid)."""
    uuid = dashboard.controls.handles[("gait", "n_steps")]._impl.uuid
    return page.locator(f"[id='{uuid}']").locator("xpath=..").locator("input:not([type=hidden])")


def test_the_watchers_page_shows_the_walk_and_changes_nothing(room, tmp_path) -> None:
    dashboard, port = room
    with sync_api.sync_playwright() as p:
        browser = launch_chromium(p)
        try:
            watcher = browser.new_page(viewport={"width": 1200, "height": 760})
            watcher.goto(watch_url(f"http://127.0.0.2:{port}"))
            watcher.get_by_text("You are watching").first.wait_for(timeout=60_000)
            watcher.get_by_text("real-time ×").first.wait_for(timeout=10_000)  # the status, live
            assert {dashboard.audience.role(c) for c in dashboard.server.get_clients()} == {WATCHER}
            # the sliders are greyed out on this page only; a typed value is refused by the
            # server and the box shows the walk's value again
            assert watcher.locator(".mantine-Slider-thumb[data-disabled]").count() >= 5
            n = dashboard.controls.handles[("gait", "n_steps")]
            before, version = n.value, dashboard.version
            box = n_box(watcher, dashboard)
            box.fill(str(before + 3))
            box.press("Enter")
            assert wait_for(lambda: box.input_value() == str(before), 10)
            watcher.screenshot(path=tmp_path / "watcher.png")
            assert dashboard.version == version and n.value == before

            presenter = browser.new_page(viewport={"width": 1200, "height": 760})
            presenter.goto(presenter_url(f"http://127.0.0.1:{port}", KEY))
            presenter.get_by_text("T_ss [s]").wait_for(timeout=60_000)
            assert wait_for(
                lambda: PRESENTER in {dashboard.audience.role(c)
                                      for c in dashboard.server.get_clients()}, 30,
            )  # fmt: skip
            assert presenter.locator(".mantine-Slider-thumb[data-disabled]").count() == 0
            box = n_box(presenter, dashboard)
            box.fill(str(before + 2))
            box.press("Enter")
            assert wait_for(lambda: dashboard.config.gait.n_steps == before + 2, 20)
            # the watcher sees the presenter's change
            assert wait_for(lambda: n_box(watcher, dashboard).input_value() == str(before + 2))
        finally:
            browser.close()
