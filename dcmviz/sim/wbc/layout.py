"""Where q̈ and each foot wrench sit inside the QP's decision vector ``x``."""

from __future__ import annotations

from dcmviz.robots import SIDES


class Layout:
    """Index ranges of q̈ and of each foot wrench inside x."""

    def __init__(self, nv: int) -> None:
        self.nv = nv
        self.wrench = {s: slice(nv + 6 * i, nv + 6 * i + 6) for i, s in enumerate(SIDES)}
        self.nx = nv + 12
