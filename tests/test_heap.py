"""The dashboard's heap gives memory back after large blocks come and go (issue 25's soak).

glibc raises its mmap threshold to the size of a freed mapped block; the blocks allocated below it
afterwards come from the heap, between small objects that live on, and stay in the process when
freed (:mod:`dcmviz.dashboard.heap`).  Allocator behaviour is only seen in the resident size, so
these tests measure it, each in a fresh process (no earlier allocation in the way), with a
pattern of the dashboard's: a 20 MB block freed (a time-buffer column at a robot switch), then 1 MB
blocks (a recording's bytes, meshes, plot windows) interleaved with small blocks that are kept.
"""

from __future__ import annotations

import ctypes
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

SCRIPT = """
import importlib.util
import sys
import numpy as np

# heap.py alone (its package would import viser and the robots: their allocations would decide
# where the blocks below land)
spec = importlib.util.spec_from_file_location("heap", "dcmviz/dashboard/heap.py")
heap = importlib.util.module_from_spec(spec)
spec.loader.exec_module(heap)

def rss():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096

fixed = sys.argv[1] == "fixed"
if fixed and not heap.fix_mmap_threshold():
    print("unsupported")
    raise SystemExit
big = np.ones(20_000_000 // 8)  # a mapped block freed: the dynamic threshold becomes 20 MB
del big
base = rss()
blocks, kept = [], []
for _ in range(200):
    blocks.append(np.ones(1_000_000 // 8))  # 1 MB, touched
    kept.append(bytes(4000))  # a small block that lives on, from malloc (> pymalloc's 512 B)
peak = rss()
del blocks
print(peak - base, rss() - base)
"""


def _held_after_free(mode: str) -> tuple[float, float]:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, cwd=ROOT,
        timeout=120, check=True,
    )  # fmt: skip
    if out.stdout.strip() == "unsupported":
        pytest.skip("no mallopt in this C library (the heap fix is glibc's)")
    grown, held = (float(v) for v in out.stdout.split())
    return grown, held


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_fixed_mmap_threshold_gives_freed_blocks_back() -> None:
    grown, held = _held_after_free("fixed")
    assert grown > 150e6  # the 200 MB were resident
    assert held < 0.05 * grown, (grown, held)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's allocator")
def test_glibc_dynamic_threshold_keeps_them_which_is_why_the_fix_exists() -> None:
    """The same pattern without the fix: the freed 1 MB blocks stay resident (the soak's climb).
    If a C library stops doing this, the fix is harmless and this test says so."""
    if not hasattr(ctypes.CDLL(None), "mallopt"):
        pytest.skip("not glibc")
    grown, held = _held_after_free("glibc")
    assert grown > 150e6
    assert held > 0.5 * grown, (grown, held)


def test_serve_fixes_the_threshold_before_the_dashboard_starts(monkeypatch) -> None:
    import dcmviz.dashboard.dashboard as dashboard_module
    from dcmviz.config import Config

    calls: list[str] = []
    monkeypatch.setattr(dashboard_module, "fix_mmap_threshold", lambda: calls.append("fix"))

    class Started(Exception):
        pass

    def refuse(*args, **kwargs):
        calls.append("dashboard")
        raise Started

    monkeypatch.setattr(dashboard_module, "Dashboard", refuse)
    with pytest.raises(Started):
        dashboard_module.serve(Config(), host="127.0.0.1", port=0, fig1a="panel")
    assert calls == ["fix", "dashboard"]
