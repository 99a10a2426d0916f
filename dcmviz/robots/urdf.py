"""URDF editing for a robot file: the legs found from the feet, the rest locked at the posture, the
sole links added, geometry dropped (the text both Pinocchio and MuJoCo are built from).

* the leg joints are the movable joints on the chain from the root link to each foot's link;
  ``joints.keep`` adds actuated joints, every other movable joint is locked at the posture (it
  becomes a fixed joint whose origin absorbs ``R_axis(q)``);
* every foot gets a ``left_sole_link``/``right_sole_link`` at the centre of its sole rectangle
  (``feet.<side>.link`` + ``offset``; a URDF link of that name with zero offset is used as is);
* visuals and collision meshes are dropped.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Iterator

import numpy as np

from dcmviz.robots.feet import SIDES
from dcmviz.robots.file import RobotFile
from dcmviz.robots.file import file_error as _err
from dcmviz.robots.legs import find_legs

MOVABLE = ("revolute", "continuous", "prismatic")


def srdf_state(rf: RobotFile) -> tuple[dict[str, float], np.ndarray | None]:
    """Joint angles of ``model.reference_posture`` in ``model.srdf`` (empty without one) and the
    base orientation its ``root_joint`` gives (quaternion x, y, z, w; None without one)."""
    if rf.srdf_path is None or rf.model.reference_posture is None:
        return {}, None
    try:
        root = ET.parse(rf.srdf_path).getroot()
    except ET.ParseError as err:
        raise _err(rf, f"model.srdf = {rf.model.srdf!r}: not valid XML ({err})") from None
    states = [s.get("name") for s in root.iter("group_state")]
    for state in root.iter("group_state"):
        if state.get("name") == rf.model.reference_posture:
            joints = {
                j.get("name"): float(j.get("value"))
                for j in state.iter("joint")
                if j.get("name") != "root_joint" and j.get("value") is not None
            }
            base = None
            for j in state.iter("joint"):
                if j.get("name") == "root_joint" and j.get("value") is not None:
                    base = _root_quaternion(rf, j.get("value"))
            return joints, base
    raise _err(
        rf,
        f"model.reference_posture = {rf.model.reference_posture!r}: no such <group_state> in "
        f"{os.path.basename(rf.srdf_path)}; expected one of {', '.join(map(str, states)) or '(none)'}",
    )


def _root_quaternion(rf: RobotFile, value: str) -> np.ndarray:
    """The orientation (x, y, z, w) of an SRDF ``root_joint`` value "x y z qx qy qz qw"."""
    try:
        numbers = np.array([float(v) for v in value.split()])
    except ValueError:
        numbers = np.zeros(0)
    if (
        numbers.shape != (7,)
        or not np.all(np.isfinite(numbers))
        or not (abs(np.linalg.norm(numbers[3:]) - 1.0) < 1e-3)
    ):
        raise _err(
            rf,
            f"model.srdf: root_joint = {value!r} in <group_state "
            f"{rf.model.reference_posture!r}>: expected 7 numbers, a position and a unit "
            "quaternion (x y z qx qy qz qw)",
        )
    return numbers[3:] / np.linalg.norm(numbers[3:])


POINT_MASS_RADIUS_M = 0.01  # a link given as a point mass (zero inertia) becomes a sphere this big


def _regularise_inertia(link: ET.Element) -> None:
    """A link with mass but a singular inertia (a point mass, as some URDFs give; MuJoCo refuses
    it) gets the inertia of a solid sphere of POINT_MASS_RADIUS_M added: 2/5 m r² on the
    diagonal, a few 1e-5 kg m² for a link of some 100 g."""
    inertial = link.find("inertial")
    if inertial is None or inertial.find("mass") is None or inertial.find("inertia") is None:
        return
    mass = float(inertial.find("mass").get("value", "0"))
    inertia = inertial.find("inertia")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    v = {k: float(inertia.get(k, "0")) for k in keys}
    matrix = np.array(
        [
            [v["ixx"], v["ixy"], v["ixz"]],
            [v["ixy"], v["iyy"], v["iyz"]],
            [v["ixz"], v["iyz"], v["izz"]],
        ]
    )
    sphere = 0.4 * mass * POINT_MASS_RADIUS_M**2
    if mass <= 0.0 or float(np.linalg.eigvalsh(matrix).min()) > 1e-3 * sphere:
        return
    for k in ("ixx", "iyy", "izz"):
        inertia.set(k, repr(v[k] + sphere))


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: R = I + sin θ [a]× + (1 - cos θ) [a]×²."""
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def parse_urdf(rf: RobotFile) -> ET.Element:
    try:
        return ET.parse(rf.urdf_path).getroot()
    except ET.ParseError as err:
        raise _err(rf, f"model.urdf = {rf.model.urdf!r}: the URDF does not load: {err}") from None


def urdf_legs(rf: RobotFile, root: ET.Element) -> dict[str, tuple[str, ...]]:
    """The movable joints from the root link to each foot's link, hip to ankle."""
    links = [link.get("name") for link in root.findall("link")]
    parent_joint: dict[str, ET.Element] = {}
    for joint in root.findall("joint"):
        child = joint.find("child")
        if child is not None:
            parent_joint[child.get("link")] = joint
    roots = [n for n in links if n not in parent_joint]

    def chain_of(foot: str) -> Iterator[tuple[str, str]]:
        link = foot
        while link in parent_joint:
            joint = parent_joint[link]
            if joint.get("type") in MOVABLE:
                yield joint.get("name"), joint.get("type")
            link = joint.find("parent").get("link")

    return find_legs(
        rf, links, "link", os.path.basename(rf.urdf_path), chain_of, "revolute",
        f"link {(roots or ['?'])[0]!r}",
    )  # fmt: skip


def edit_urdf(
    rf: RobotFile,
    root: ET.Element,
    actuated: set[str],
    nominal: dict[str, float],
    locked: dict[str, float],
) -> tuple[str, dict[str, str | None]]:
    """The URDF text with the non-actuated joints locked, soles added and geometry removed;
    ``locked`` receives every locked joint and its angle (rad).  Returns the text and, per side,
    the link a sole link was added under (None when the URDF's ``<side>_sole_link`` is used)."""
    import pinocchio as pin

    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
        _regularise_inertia(link)
    for tag in ("transmission", "gazebo", "material"):
        for el in root.findall(tag):
            root.remove(el)
    for joint in root.findall("joint"):
        jtype = joint.get("type")
        name = joint.get("name")
        if jtype in MOVABLE and name not in actuated:
            if jtype == "prismatic":
                raise _err(rf, f"joints: cannot lock prismatic joint {name!r}")
            angle = nominal.get(name, 0.0)
            locked[name] = angle
            origin = joint.find("origin")
            if origin is None:
                origin = ET.SubElement(joint, "origin", xyz="0 0 0", rpy="0 0 0")
            rpy = np.array([float(v) for v in origin.get("rpy", "0 0 0").split()])
            axis_el = joint.find("axis")
            axis = np.array(
                [float(v) for v in (axis_el.get("xyz") if axis_el is not None else "1 0 0").split()]
            )
            rot = pin.rpy.rpyToMatrix(*rpy) @ _axis_rotation(axis, angle)
            origin.set("rpy", " ".join(f"{v:.17g}" for v in pin.rpy.matrixToRpy(rot)))
            joint.set("type", "fixed")
            for tag in ("mimic", "limit", "axis", "dynamics", "safety_controller"):
                for el in joint.findall(tag):
                    joint.remove(el)
    links = {link.get("name") for link in root.findall("link")}
    sole_parent: dict[str, str | None] = {}
    for side in SIDES:
        foot = getattr(rf.feet, side)
        name = f"{side}_sole_link"
        if foot.link == name and not any(foot.offset):
            sole_parent[side] = None
            continue
        if name in links:
            raise _err(
                rf,
                f"feet.{side}.link = {foot.link!r}: the URDF already has a link {name!r}; "
                f"expected the sole on it: feet.{side}.link = {name!r} with a zero offset",
            )
        sole_parent[side] = foot.link
        link = ET.SubElement(root, "link", name=name)
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
        ET.SubElement(inertial, "mass", value="1e-4")
        ET.SubElement(
            inertial, "inertia", ixx="1e-8", ixy="0", ixz="0", iyy="1e-8", iyz="0", izz="1e-8"
        )
        joint = ET.SubElement(root, "joint", name=f"{side}_sole_fix_joint", type="fixed")
        ET.SubElement(joint, "parent", link=foot.link)
        ET.SubElement(joint, "child", link=name)
        ET.SubElement(joint, "origin", xyz=" ".join(str(v) for v in foot.offset), rpy="0 0 0")
    return ET.tostring(root, encoding="unicode"), sole_parent
