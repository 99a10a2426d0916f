"""Hand the C heap freed by a large, short-lived allocation back to the system.

glibc keeps freed memory in its arenas (one per thread that allocated), so after loading meshes,
replacing a simulation (MuJoCo and Pinocchio models and data) or writing out a recording, the
peak stays in the process's RSS and a long session's RSS climbs with every such event although
nothing is alive.  ``malloc_trim(0)`` returns the free pages; elsewhere (no glibc) it is a no-op.
"""

from __future__ import annotations

import ctypes


def release_freed_memory() -> None:
    """glibc's ``malloc_trim(0)``; nothing where it does not exist."""
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (AttributeError, OSError):
        pass
