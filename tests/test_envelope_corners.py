"""Talos in MuJoCo at corners of its walking envelope (issue 9, item 4), checked from the runner's
CSV alone: the measured DCM is rebuilt from the CoM column by central differences,
ξ = x + b ẋ (eq. 1), and compared with the ``xi_ref`` column. A walk passes with a horizontal
error < 3 cm and a vertical one < 2 cm at every tick and < 1 cm at the end, without falling.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from dcmviz import GRAVITY
from dcmviz.run import main as run

PRESET = Path(__file__).resolve().parents[1] / "presets" / "walk_forward.toml"
HORIZONTAL_M, VERTICAL_M, FINAL_M = 0.03, 0.02, 0.01
N_STEPS = 8

# mode, step length (m), width (m), turn (rad), T_ss (s), T_ds (s), CoM height (m), order, k_ξ,
# step adjustment, observer
CORNERS = {
    "backward narrow turning fast steps, CoM 0.90 m, continuous": (
        "continuous", -0.15, 0.16, -0.3, 0.5, 0.1, 0.90, 1, 6.0, True, False
    ),
    "backward wide turning slow steps, CoM 0.72 m": (
        "plan", -0.15, 0.30, 0.3, 1.2, 0.1, 0.72, 5, 6.0, False, False
    ),
    "0.40 m wide turning steps, slow, k_xi 1, CoM 0.76 m": (
        "plan", 0.40, 0.30, 0.3, 1.2, 0.4, 0.76, 1, 1.0, False, True
    ),
    "0.30 m turning steps in 0.6 s, CoM 0.86 m": (
        "plan", 0.30, 0.20, -0.3, 0.5, 0.1, 0.86, 3, 6.0, False, False
    ),
}  # fmt: skip


def _walk(tmp_path: Path, corner: tuple) -> tuple[dict, dict[str, np.ndarray], float]:
    mode, length, width, turn, t_ss, t_ds, height, order, k_xi, adjust, observe = corner
    b = math.sqrt(height / GRAVITY)
    duration = 8.0 if mode == "continuous" else 1.0 + N_STEPS * (t_ss + t_ds) + 1.0 + 1.0
    overrides = {
        "gait.mode": f'"{mode}"',
        "gait.n_steps": N_STEPS,
        "gait.step_length": length,
        "gait.step_width": width,
        "gait.turn": turn,
        "gait.t_ss": t_ss,
        "gait.t_ds": t_ds,
        "dcm.order": order,
        "dcm.b": repr(b),
        "control.k_xi": k_xi,
        "control.step_adjustment": str(adjust).lower(),
        "control.observer": str(observe).lower(),
    }
    csv_path, json_path = tmp_path / "walk.csv", tmp_path / "walk.json"
    argv = [str(PRESET), "--sim", "mujoco", "--duration", str(duration)]
    argv += ["--csv", str(csv_path), "--json", str(json_path)]
    for key, value in overrides.items():
        argv += ["--set", f"{key}={value}"]
    assert run(argv) == 0
    table = np.genfromtxt(csv_path, delimiter=",", names=True, dtype=None, encoding="utf-8")
    columns = {
        name: np.stack([table[f"{name}_{a}"] for a in "xyz"], axis=1) for name in ("com", "xi_ref")
    }
    columns["t"] = table["t"]
    return json.loads(json_path.read_text()), columns, b


@pytest.mark.slow
@pytest.mark.parametrize("corner", list(CORNERS))
def test_talos_tracks_an_envelope_corner(tmp_path, corner):
    result, c, b = _walk(tmp_path, CORNERS[corner])
    assert not result["fell"]
    dt = float(np.median(np.diff(c["t"])))
    # row k holds ξ_ref of tick k and the CoM measured after it: ξ of tick k is the CoM of row
    # k - 1 plus b times its central difference
    com = c["com"]
    xi = com[1:-1] + b * (com[2:] - com[:-2]) / (2.0 * dt)
    error = xi - c["xi_ref"][2:]
    horizontal = np.hypot(error[:, 0], error[:, 1])
    vertical = np.abs(error[:, 2])
    assert horizontal.max() < HORIZONTAL_M, f"horizontal {horizontal.max() * 100:.2f} cm"
    assert vertical.max() < VERTICAL_M, f"vertical {vertical.max() * 100:.2f} cm"
    assert np.linalg.norm(error[-1]) < FINAL_M, f"final {np.linalg.norm(error[-1]) * 100:.2f} cm"
