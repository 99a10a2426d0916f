"""Issue 22, item 4: arms a robot file keeps take part of a torso push's angular momentum.

``robots/talos_arms.toml`` is the built-in Talos with its shoulders and elbows actuated
(``[joints] keep``), nothing else changed.  Pushed at its torso towards its stance foot at mid
single support (walk_forward, step timing, observer off), the locked-arm Talos is held to the
stance-edge bound with the push's moment at the feet (29.3 N·s; it survives 27 and falls from 28,
tests/test_sweep_bounds.py), because the trunk's return of the stored momentum keeps the CMP
inside the CoP.  With the arms, the whole-body QP swings them out and they carry part of that
momentum: it survives up to 30 N·s and falls at 31.
"""

from __future__ import annotations

import math
from pathlib import Path

import pinocchio as pin
import pytest

from dcmviz.config import load_preset
from dcmviz.robots import load_robot
from dcmviz.session import Session
from dcmviz.sweep.bounds import stance_edge_bound
from dcmviz.sweep.search import push_window

ROOT = Path(__file__).resolve().parents[1]
ARMS = str(ROOT / "robots" / "talos_arms.toml")
DURATION_S = 0.2


def config(model: str):
    return load_preset(ROOT / "presets" / "walk_forward.toml").replace(
        pushes=[],
        control={"recovery": "multi_step_timing", "observer": False},
        robot={"model": model},
    )


def push(model: str, impulse: float, watch=None) -> bool:
    """True if the robot survives a torso push of ``impulse`` N·s towards its left stance foot at
    mid single support of step 4; ``watch(session)`` is called every tick of the push's first
    0.6 s."""
    cfg = config(model)
    start = push_window(cfg, 4, 0.5)[0]
    session = Session(cfg, backend="mujoco")
    session.push((0.0, impulse / DURATION_S, 0.0), DURATION_S, body="torso", start=start)
    while session.t < start + 1.8 and not session.fell:
        session.step()
        if watch is not None and start <= session.t < start + 0.6:
            watch(session)
    return not session.fell


def test_the_arms_file_is_talos_with_eight_more_joints() -> None:
    arms, talos = load_robot(ARMS), load_robot("talos")
    assert arms.nu == talos.nu + 8
    assert arms.spec.mass_kg == talos.spec.mass_kg
    assert abs(arms.spec.com_height_m - talos.spec.com_height_m) < 1e-9
    kept = [n for n in arms.pin_model.names if n.startswith("arm_")]
    assert len(kept) == 8


@pytest.mark.parametrize("impulse", [28.0, 30.0])
def test_arms_catch_a_push_beyond_the_bound_with_the_moment_at_the_feet(impulse: float) -> None:
    """28 and 30 N·s (0.96 and 1.02 of the bound with the moment at the feet): the arms survive
    both, the locked arms neither; and the arms do carry angular momentum: their part of the
    centroidal momentum about x (Pinocchio's centroidal map on the simulated state, the joint
    velocities of the arms) reaches ≥ 1.5 N·m·s with the sign of the push's moment (−x: a push
    to +y above the CoM)."""
    bound = stance_edge_bound(config("talos"), 4, 0.5, DURATION_S, math.pi / 2,
                              backend="mujoco", body="torso")  # fmt: skip
    assert 0.9 * bound < impulse < 1.05 * bound
    model = load_robot(ARMS).pin_model
    data = model.createData()
    columns = [model.joints[model.getJointId(n)].idx_v for n in model.names if n.startswith("arm_")]
    carried = []

    def watch(session: Session) -> None:
        backend = session.backend
        scene, d = backend.robot.mujoco, backend.data  # MuJoCo's state in Pinocchio's order
        q, v = scene.q_pin(d.qpos), scene.v_pin(d.qpos, d.qvel)
        centroidal = pin.computeCentroidalMap(model, data, q)
        carried.append(float(centroidal[3, columns] @ v[columns]))

    assert push(ARMS, impulse, watch)
    assert min(carried) < -1.5
    assert not push("talos", impulse)
