"""The browser dashboard (viser): tune DCM walking, watch the preview, push the robot.

``python app.py`` starts it; :func:`serve` does the same from Python.
"""

from __future__ import annotations

from dcmviz.dashboard.dashboard import Dashboard, serve

__all__ = ["Dashboard", "serve"]
