"""A robot file → an edited model (URDF or MJCF), a Pinocchio model, the nominal standing posture
and every number derived from them (:class:`RobotModel`).

The model text is edited once (:mod:`.urdf`, :mod:`.mjcf`) and both simulators are built from
it (:mod:`.robot` adds MuJoCo); the posture comes from :mod:`.posture`, the numbers from
:mod:`.derive`.  Everything here raises :class:`~dcmviz.robots.file.RobotFileError` naming the
key of the robot file and what was expected; nothing is cached before the whole check has passed.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from dcmviz.robots.derive import Derived, LegLimits, derive, robot_spec
from dcmviz.robots.feet import SIDES
from dcmviz.robots.file import RobotFile
from dcmviz.robots.file import file_error as _err
from dcmviz.robots.legs import suggest as _suggest
from dcmviz.robots.posture import standing_posture
from dcmviz.robots.urdf import MOVABLE, edit_urdf, parse_urdf, srdf_state, urdf_legs

# actuator defaults per kg of robot (Talos: 0.05 kg m², 0.2 N m s/rad at 90.27 kg)
ARMATURE_PER_KG = 0.05 / 90.27
DAMPING_PER_KG = 0.2 / 90.27


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A robot file built into a Pinocchio model with its nominal standing posture."""

    file: RobotFile
    # the edited model text, URDF or MJCF (``is_mjcf``): upper body locked, soles added, no geometry
    urdf_text: str
    pin_model: object  # pinocchio.Model (free flyer), armature set
    joint_names: tuple[str, ...]  # actuated joints, Pinocchio's order
    legs: dict[str, tuple[str, ...]]  # side -> leg joints, hip to ankle
    locked: dict[str, float]  # locked joint -> angle, rad
    nominal: dict[str, float]  # posture of every joint (locked or not) before solving, rad
    sole_parent: dict[str, str | None]  # side -> link a sole link was added under (None: URDF's)
    sole_offset: dict[str, tuple[float, float, float]]
    q_nominal: np.ndarray  # Pinocchio q of the standing posture (soles on z = 0, centred at x = 0)
    limits: dict[str, LegLimits]  # per actuated joint
    armature: float
    damping: float
    derived: Derived
    spec: object = field(repr=False)  # dcmviz.robots.spec.RobotSpec (pins applied)

    @property
    def is_mjcf(self) -> bool:
        """True if the robot file names an MJCF model (``urdf_text`` is then MJCF)."""
        return bool(self.file.mjcf_path)


def _pinocchio_from_mjcf(rf: RobotFile, text: str):
    """Pinocchio's model of the edited MJCF text, with a free-flyer root joint."""
    import tempfile

    import pinocchio as pin

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "robot.xml")
        with open(path, "w", encoding="utf-8") as f:
            f.write(text)
        try:
            if hasattr(pin, "buildModelFromMJCFAndRootJoint"):  # pin ≥ 4.1
                built = pin.buildModelFromMJCFAndRootJoint(path, pin.JointModelFreeFlyer())
            else:  # (model, constraints): the edit leaves no equality constraints
                built = pin.buildModelFromMJCF(path, pin.JointModelFreeFlyer(), "root_joint")
        except Exception as err:  # noqa: BLE001 - Pinocchio raises plain exceptions
            raise _err(
                rf, f"model.mjcf = {rf.model.mjcf!r}: Pinocchio does not load the MJCF: {err}"
            ) from None
    return built[0] if isinstance(built, tuple) else built


@dataclass(frozen=True)
class _Source:
    """The model file as read: its kind, legs, movable joints and the parsed document."""

    kind: str  # "URDF" | "MJCF"
    legs: dict[str, tuple[str, ...]]
    movable: dict[str, str]  # joint -> type
    document: object  # the URDF's ElementTree root or the MJCF source (dcmviz.robots.mjcf)


def _read_source(rf: RobotFile) -> _Source:
    if rf.mjcf_path:
        from dcmviz.robots import mjcf

        src = mjcf.load_mjcf(rf)
        return _Source("MJCF", mjcf.legs(rf, src), dict(src.movable), src)
    root = parse_urdf(rf)
    movable = {
        j.get("name"): j.get("type") for j in root.findall("joint") if j.get("type") in MOVABLE
    }
    return _Source("URDF", urdf_legs(rf, root), movable, root)


def _actuated(rf: RobotFile, src: _Source) -> set[str]:
    """The leg joints and ``joints.keep``; ``joints.lock`` checked to cover the rest."""
    movable = src.movable
    for name in rf.joints.keep:
        if movable.get(name) != "revolute":
            raise _err(
                rf,
                f"joints.keep: {name!r} is not a revolute joint of the {src.kind}; expected "
                "joints to actuate besides the legs",
            )
    actuated = set(src.legs["left"]) | set(src.legs["right"]) | set(rf.joints.keep)
    if rf.joints.lock is not None:
        for name in rf.joints.lock:
            if name not in movable or name in actuated:
                raise _err(
                    rf,
                    f"joints.lock: {name!r} is "
                    f"{'a leg or kept joint' if name in actuated else 'not a movable joint'}; "
                    "expected a movable joint that is neither a leg joint nor in joints.keep",
                )
        loose = sorted(set(movable) - actuated - set(rf.joints.lock))
        if loose:
            raise _err(
                rf,
                f"joints.lock: {', '.join(loose)} neither locked nor kept; expected every "
                "movable joint off the legs in joints.lock or joints.keep",
            )
    return actuated


def _reference_posture(rf: RobotFile, src: _Source) -> tuple[dict[str, float], np.ndarray | None]:
    """Joint angles of the reference posture (SRDF group state or MJCF key) with ``posture``,
    and the base orientation it gives (quaternion x, y, z, w; None if it gives none)."""
    if src.kind == "MJCF" and rf.srdf_path is None and rf.model.reference_posture is not None:
        from dcmviz.robots import mjcf

        nominal, base = mjcf.keyframe_posture(rf, src.document)
    else:
        nominal, base = srdf_state(rf)
    for name in rf.posture:
        if name not in src.movable:
            raise _err(
                rf,
                f"posture.{name}: no movable joint of that name in the {src.kind}; expected one "
                f"of {_suggest(sorted(src.movable), ('hip', 'knee', 'ankle'))}",
            )
    nominal.update(rf.posture)
    return nominal, base


def _edited_model(rf: RobotFile, src: _Source, actuated: set[str], nominal: dict[str, float]):
    """(edited text, Pinocchio model, locked joints, sole parents) of the model file."""
    import pinocchio as pin

    locked: dict[str, float] = {}
    if src.kind == "MJCF":
        from dcmviz.robots import mjcf

        text, sole_parent = mjcf.edit_mjcf(rf, src.document, actuated, nominal, locked)
        return text, _pinocchio_from_mjcf(rf, text), locked, sole_parent
    text, sole_parent = edit_urdf(rf, src.document, actuated, nominal, locked)
    try:
        pm = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
    except Exception as err:  # noqa: BLE001 - Pinocchio raises plain exceptions
        raise _err(rf, f"model.urdf = {rf.model.urdf!r}: the URDF does not load: {err}") from None
    return text, pm, locked, sole_parent


def _set_torque_limits(rf: RobotFile, pm, joint_names: tuple[str, ...]) -> None:
    """``[actuators] torque_limits`` and ``torque_scale`` into the model's effort limits (the
    one place the QP, MuJoCo's motors and the derived numbers read them from)."""
    act = rf.actuators
    for name, nm in act.torque_limits.items():
        if name not in joint_names:
            raise _err(
                rf,
                f"actuators.torque_limits: {name!r} is not an actuated joint; expected one of "
                f"{', '.join(joint_names)} (the legs' and joints.keep's)",
            )
        pm.effortLimit[6 + joint_names.index(name)] = nm
    if act.torque_scale != 1.0:
        pm.effortLimit[6:] *= act.torque_scale


def _limits(rf: RobotFile, pm, joint_names: tuple[str, ...]) -> dict[str, LegLimits]:
    limits = {}
    for i, name in enumerate(joint_names):
        lim = LegLimits(
            float(pm.lowerPositionLimit[7 + i]),
            float(pm.upperPositionLimit[7 + i]),
            float(pm.effortLimit[6 + i]),
            float(pm.velocityLimit[6 + i]),
        )
        if not (lim.torque_nm > 0 and lim.lower_rad < lim.upper_rad):
            raise _err(
                rf,
                f"model.urdf: joint {name!r} has no <limit effort lower upper>; expected torque "
                "and position limits on every actuated joint (a torque limit may also be given "
                "in [actuators] torque_limits)"
                if rf.mjcf_path == ""
                else f"model.mjcf: joint {name!r} has no range or no torque limit; expected a "
                "range and an actuatorfrcrange (or a motor with a ctrlrange) on every actuated "
                "joint",
            )
        limits[name] = lim
    return limits


def build_from_file(rf: RobotFile) -> RobotModel:
    """Build and check a parsed robot file; RobotFileError naming the key otherwise."""
    import pinocchio as pin

    src = _read_source(rf)
    actuated = _actuated(rf, src)
    nominal, base = _reference_posture(rf, src)
    text, pm, locked, sole_parent = _edited_model(rf, src, actuated, nominal)
    joint_names = tuple(pm.names[2:])
    if set(joint_names) != actuated:  # pragma: no cover - the edit keeps exactly these
        raise _err(rf, f"joints: unexpected actuated joints {joint_names}")
    sole_frames = {s: pm.getFrameId(f"{s}_sole_link") for s in SIDES}
    _set_torque_limits(rf, pm, joint_names)
    limits = _limits(rf, pm, joint_names)
    q = standing_posture(rf, pm, joint_names, nominal, sole_frames, base)
    mass = float(pin.computeTotalMass(pm))
    armature = rf.actuators.armature
    armature = ARMATURE_PER_KG * mass if armature is None else armature
    damping = rf.actuators.damping
    damping = DAMPING_PER_KG * mass if damping is None else damping
    pm.armature[6:] = armature
    derived = derive(pm, q, sole_frames, src.legs, joint_names, limits, rf)
    return RobotModel(
        file=rf,
        urdf_text=text,
        pin_model=pm,
        joint_names=joint_names,
        legs=src.legs,
        locked=locked,
        nominal=nominal,
        sole_parent=sole_parent,
        sole_offset={s: tuple(getattr(rf.feet, s).offset) for s in SIDES},
        q_nominal=q,
        limits=limits,
        armature=float(armature),
        damping=float(damping),
        derived=derived,
        spec=robot_spec(rf, derived),
    )
