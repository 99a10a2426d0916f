"""A long-running dashboard's heap: glibc's mmap threshold held fixed (issue 25's soak).

glibc serves an allocation above its mmap threshold (128 KiB at start) with a mapping of its own,
returned to the system when freed.  By default the threshold is *dynamic*: freeing such a mapped
block raises it to that block's size (up to 32 MiB).  The dashboard frees large blocks now and
then: the time buffer's ring columns (≈ 40 MB) when another robot's walk starts, a finished
recording's bytes, a robot's meshes.  After the first of these, every allocation below the new
threshold comes from the heap instead, between small objects that live on (the buffer's
checkpoints, plans, scene messages), and the heap cannot give it back.  Measured without a browser
(``session.step`` and the time buffer, Talos ↔ G1 ↔ stairs, 80 s of walking between switches): the
RSS after each round of presets rose 331 → 348 → 373 → 380 → 405 MB; with the threshold fixed it
stayed at 331–332 MB.

:func:`fix_mmap_threshold` sets it once for the process (``mallopt(M_MMAP_THRESHOLD, …)``, which
also turns the dynamic adjustment off, as the ``MALLOC_MMAP_THRESHOLD_`` environment variable
would); :func:`~dcmviz.dashboard.serve` calls it.  On a C library without ``mallopt`` (macOS,
musl) it does nothing and says so by returning False.
"""

from __future__ import annotations

import ctypes
import sys

M_MMAP_THRESHOLD = -3  # glibc's malloc.h
MMAP_THRESHOLD_BYTES = 128 * 1024  # glibc's starting value, kept


def fix_mmap_threshold(nbytes: int = MMAP_THRESHOLD_BYTES) -> bool:
    """Hold glibc's mmap threshold at ``nbytes`` for this process; True if it was set."""
    if not sys.platform.startswith("linux"):
        return False
    try:  # the C library the process runs on (no ldconfig lookup at start-up)
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return mallopt(M_MMAP_THRESHOLD, int(nbytes)) == 1
