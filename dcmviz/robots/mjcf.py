"""An MJCF robot model (MuJoCo XML) → the edited MJCF both simulators are built from.

The same edit as for a URDF (:mod:`dcmviz.robots.model`), on MuJoCo's ``MjSpec``:

* every body gets its compiled inertia as an explicit ``<inertial>``, then every geom, mesh,
  texture, material, site, actuator, sensor, tendon, contact pair/exclude and keyframe is
  removed (only the soles will collide; meshes need not resolve for Pinocchio);
* body poses and joint ranges are written from the compiled model (radians, quaternions), and a
  hinge's ``ref`` is moved into its body's pose, so that q = 0 means the same in MuJoCo and
  Pinocchio;
* every hinge joint not actuated is locked at the posture: removed, its body turned by
  ``R_axis(q)`` about the joint's anchor;
* the root body's free joint is removed (the simulators add their own floating base);
* every foot gets a ``left_sole_link``/``right_sole_link`` body at its sole centre;
* each actuated joint carries its torque limit as ``actuatorfrcrange`` (from the joint's own
  ``actuatorfrcrange``, else from a motor on it: |gear| × ctrlrange or its forcerange).

What is refused (RobotFileError naming the key): a model that does not compile, equality
constraints, ``<frame>`` elements, more than one body under ``<worldbody>``, a body with more
than one joint, slide or ball joints off the legs, leg joints that are not hinges.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from dcmviz.robots.file import RobotFile
from dcmviz.robots.file import file_error as _err
from dcmviz.robots.legs import find_legs

SIDES = ("left", "right")
_KIND = {0: "free", 1: "ball", 2: "prismatic", 3: "revolute"}  # mjtJoint → URDF-like words


@dataclass(frozen=True, eq=False)
class MjcfSource:
    """An MJCF model as written (``spec``) and compiled (``model``)."""

    spec: object  # mujoco.MjSpec
    model: object  # mujoco.MjModel
    movable: dict[str, str]  # joint -> "revolute" | "prismatic" | "ball" (free joints left out)
    bodies: tuple[str, ...]


def load_mjcf(rf: RobotFile) -> MjcfSource:
    """Read and compile ``model.mjcf``; RobotFileError if it does not load or uses what the
    edit cannot carry over."""
    import mujoco

    name = os.path.basename(rf.mjcf_path)
    try:
        spec = mujoco.MjSpec.from_file(rf.mjcf_path)
        model = spec.compile()
    except Exception as err:  # noqa: BLE001 - MuJoCo raises ValueError with its message
        raise _err(rf, f"model.mjcf = {rf.model.mjcf!r}: the MJCF does not load: {err}") from None
    refuse = []
    if model.neq:
        refuse.append(f"{model.neq} equality constraint(s); expected none (closed chains and "
                      "coupled joints are not supported)")  # fmt: skip
    if spec.frames:
        refuse.append("<frame> elements; expected bodies placed directly in their parents")
    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if len(roots) != 1:
        refuse.append(f"{len(roots)} bodies under <worldbody>; expected the robot's root body only")
    movable: dict[str, str] = {}
    for b in range(1, model.nbody):
        joints = [j for j in range(model.njnt) if model.jnt_bodyid[j] == b]
        if len(joints) > 1:
            refuse.append(
                f"body {model.body(b).name!r} has {len(joints)} joints; expected at most one per "
                "body"
            )
        for j in joints:
            kind = _KIND[int(model.jnt_type[j])]
            if kind == "free":
                if b not in roots:
                    refuse.append(f"free joint on body {model.body(b).name!r}; expected one on "
                                  "the root body only")  # fmt: skip
                continue
            if not model.joint(j).name:
                refuse.append(f"an unnamed joint on body {model.body(b).name!r}; expected names")
            movable[model.joint(j).name] = kind
    if refuse:
        raise _err(rf, f"model.mjcf = {rf.model.mjcf!r} ({name}): " + "; ".join(refuse))
    bodies = tuple(model.body(b).name for b in range(model.nbody))
    return MjcfSource(spec=spec, model=model, movable=movable, bodies=bodies)


def keyframe_posture(rf: RobotFile, src: MjcfSource) -> tuple[dict[str, float], np.ndarray | None]:
    """Joint angles of the ``<key>`` named ``model.reference_posture`` (without an SRDF) and the
    base orientation of its free joint (quaternion x, y, z, w; None without a free joint)."""
    m = src.model
    keys = [m.key(k).name for k in range(m.nkey)]
    if rf.model.reference_posture not in keys:
        raise _err(
            rf,
            f"model.reference_posture = {rf.model.reference_posture!r}: no such <key> in "
            f"{os.path.basename(rf.mjcf_path)}; expected one of {', '.join(keys) or '(none)'}",
        )
    qpos = m.key(rf.model.reference_posture).qpos
    joints = {
        m.joint(j).name: float(qpos[m.jnt_qposadr[j]])
        for j in range(m.njnt)
        if _KIND[int(m.jnt_type[j])] == "revolute"
    }
    base = None
    for j in range(m.njnt):
        if _KIND[int(m.jnt_type[j])] == "free":
            w, x, y, z = (float(v) for v in qpos[m.jnt_qposadr[j] + 3 : m.jnt_qposadr[j] + 7])
            norm = math.sqrt(w * w + x * x + y * y + z * z)
            if norm > 1e-9:
                base = np.array([x, y, z, w]) / norm
    return joints, base


def legs(rf: RobotFile, src: MjcfSource) -> dict[str, tuple[str, ...]]:
    """The joints from the root body to each foot's body, hip to ankle (hinges only)."""
    m = src.model

    def chain_of(foot: str) -> Iterator[tuple[str, str]]:
        b = m.body(foot).id
        while b > 0:
            for j in range(m.njnt):
                kind = _KIND[int(m.jnt_type[j])]
                if m.jnt_bodyid[j] == b and kind != "free":
                    yield m.joint(j).name, kind
            b = int(m.body_parentid[b])

    return find_legs(
        rf, list(src.bodies[1:]), "body", os.path.basename(rf.mjcf_path), chain_of, "hinge",
        "body",
    )  # fmt: skip


def _torque_limit(m, j: int) -> float:
    """The joint's torque limit (N m): its actuatorfrcrange, else a motor's on it, else 0."""
    if m.jnt_actfrclimited[j]:
        return float(np.max(np.abs(m.jnt_actfrcrange[j])))
    import mujoco

    best = 0.0
    for a in range(m.nu):
        if m.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_JOINT or m.actuator_trnid[a, 0] != j:
            continue
        gear = abs(float(m.actuator_gear[a, 0]))
        if m.actuator_forcelimited[a]:
            best = max(best, gear * float(np.max(np.abs(m.actuator_forcerange[a]))))
        elif (
            m.actuator_ctrllimited[a]
            and m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
            and m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE
        ):
            gain = abs(float(m.actuator_gainprm[a, 0]))
            best = max(best, gear * gain * float(np.max(np.abs(m.actuator_ctrlrange[a]))))
    return best


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    import mujoco

    out = np.empty(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def _rotate(quat: np.ndarray, v: np.ndarray) -> np.ndarray:
    import mujoco

    out = np.empty(3)
    mujoco.mju_rotVecQuat(out, np.asarray(v, float), np.asarray(quat, float))
    return out


def edit_mjcf(
    rf: RobotFile,
    src: MjcfSource,
    actuated: set[str],
    nominal: dict[str, float],
    locked: dict[str, float],
) -> tuple[str, dict[str, str | None]]:
    """The MJCF text with the non-actuated joints locked, soles added and geometry removed;
    ``locked`` receives every locked joint and its angle (rad).  Returns the text and, per side,
    the body a sole body was added under (None when the model's ``<side>_sole_link`` is used)."""
    import mujoco

    spec, m = src.spec, src.model
    # explicit inertias and canonical poses from the compiled model (before geoms go)
    for b, body in enumerate(spec.bodies):
        if b == 0:
            continue
        cb = m.body(body.name) if body.name else m.body(b)
        body.pos, body.quat = cb.pos.copy(), cb.quat.copy()
        body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
        body.mass = float(cb.mass[0])
        body.ipos, body.iquat, body.inertia = cb.ipos.copy(), cb.iquat.copy(), cb.inertia.copy()
        body.ialt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
        body.fullinertia = [math.nan] * 6
        body.explicitinertial = True
    spec.compiler.degree = False
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_AUTO
    limits = {}
    for name in actuated:
        limits[name] = _torque_limit(m, m.joint(name).id)
    for kind in ("geoms", "sites", "actuators", "sensors", "tendons", "excludes", "pairs",
                 "keys", "meshes", "textures", "materials", "hfields", "skins"):  # fmt: skip
        for el in list(getattr(spec, kind)):
            spec.delete(el)
    for joint in list(spec.joints):
        cj = m.joint(joint.name)
        kind = _KIND[int(m.jnt_type[cj.id])]
        if kind == "free":
            spec.delete(joint)
            continue
        body = joint.parent
        anchor, axis = m.jnt_pos[cj.id].copy(), m.jnt_axis[cj.id].copy()
        ref = float(m.qpos0[m.jnt_qposadr[cj.id]]) if kind == "revolute" else 0.0
        if joint.name in actuated:
            angle = -ref  # q = 0 is the body's pose: the ref moves into it
        else:
            if kind != "revolute":
                raise _err(rf, f"joints: cannot lock {kind} joint {joint.name!r}")
            locked[joint.name] = nominal.get(joint.name, 0.0)
            angle = locked[joint.name] - ref
        if angle != 0.0:
            turn = np.empty(4)
            mujoco.mju_axisAngle2Quat(turn, np.asarray(axis, float), angle)
            quat = np.asarray(body.quat, float)
            body.pos = np.asarray(body.pos, float) + _rotate(quat, anchor - _rotate(turn, anchor))
            body.quat = _quat_mul(quat, turn)
        if joint.name in actuated:
            joint.pos, joint.axis = anchor, axis
            joint.ref = 0.0
            joint.range = m.jnt_range[cj.id].copy()
            joint.limited = (
                mujoco.mjtLimited.mjLIMITED_TRUE
                if m.jnt_limited[cj.id]
                else mujoco.mjtLimited.mjLIMITED_FALSE
            )
            tau = limits[joint.name]
            joint.actfrclimited = (
                mujoco.mjtLimited.mjLIMITED_TRUE if tau > 0 else mujoco.mjtLimited.mjLIMITED_FALSE
            )
            joint.actfrcrange = [-tau, tau]
        else:
            spec.delete(joint)
    sole_parent: dict[str, str | None] = {}
    for side in SIDES:
        foot = getattr(rf.feet, side)
        name = f"{side}_sole_link"
        if foot.link == name and not any(foot.offset):
            sole_parent[side] = None
            continue
        if name in src.bodies:
            raise _err(
                rf,
                f"feet.{side}.link = {foot.link!r}: the MJCF already has a body {name!r}; "
                f"expected the sole on it: feet.{side}.link = {name!r} with a zero offset",
            )
        sole_parent[side] = foot.link
        sole = spec.body(foot.link).add_body(name=name, pos=list(foot.offset))
        sole.mass, sole.inertia = 1e-4, [1e-8, 1e-8, 1e-8]  # as a URDF's added sole link
        sole.ipos, sole.iquat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]  # (else not written)
        sole.explicitinertial = True
    try:
        return spec.to_xml(), sole_parent
    except Exception as err:  # noqa: BLE001 - MuJoCo raises ValueError with its message
        raise _err(
            rf, f"model.mjcf = {rf.model.mjcf!r}: the edited MJCF does not compile: {err}"
        ) from None
