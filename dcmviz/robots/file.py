"""Robot files (TOML): where a humanoid's model comes from and what cannot be derived from it.

The schema is documented for users in ``docs/robots.md``; the built-in robots are files in
``dcmviz/robots/data/`` (``talos.toml``, ``g1.toml``, ``romeo.toml``).  A file is validated as a
whole by pydantic models; errors name the key, the bad value and what was expected::

    RobotFileError: g1.toml: feet.left.size = [0.17]: expected [length, width] in m, both > 0

Only the file is read here (no Pinocchio, no MuJoCo): the links and joints it names are checked
against the URDF when the model is built (:func:`dcmviz.robots.model.build_model`).
"""

from __future__ import annotations

import importlib.metadata
import math
import os
import site
import sysconfig
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

ROBOTS_DOC = "docs/robots.md"  # the robot file schema, for users (errors point there)
DATA_DIR = Path(__file__).resolve().parent / "data"  # the built-in robot files
BUILTIN_ROBOTS: tuple[str, ...] = ("talos", "g1", "romeo")
MAX_ROBOT_FILE_BYTES = 64 * 1024


class RobotFileError(ValueError):
    """A robot file is invalid; the message names the file, the key and what was expected."""


def file_error(rf: RobotFile, message: str) -> RobotFileError:
    """``message`` (the key and what was expected) as an error of robot file ``rf``."""
    return RobotFileError(f"{os.path.basename(rf.path)}: {message}")


def example_robot_data_dir() -> str:
    """``example-robot-data``'s ``robots`` directory (its package data under the cmeel prefix).

    The wheel ships no Python module: its files are package data under
    ``cmeel.prefix/share/example-robot-data/robots``, found through the installed distribution's
    file list (``importlib.metadata``), else in every site-packages of the interpreter."""
    relative = os.path.join("cmeel.prefix", "share", "example-robot-data", "robots")
    try:
        located = str(importlib.metadata.distribution("example-robot-data").locate_file(relative))
        if os.path.isdir(located):
            return located
    except importlib.metadata.PackageNotFoundError:
        pass
    candidates = [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]]
    try:
        candidates += site.getsitepackages()
    except AttributeError:  # pragma: no cover - virtualenv without getsitepackages
        pass
    candidates.append(site.getusersitepackages())
    for base in candidates:
        path = os.path.join(base, relative)
        if os.path.isdir(path):
            return path
    raise FileNotFoundError(
        "example-robot-data not found under any site-packages/cmeel.prefix; "
        "install it with `pip install example-robot-data`"
    )


class _Table(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _finite(values: tuple[float, ...]) -> tuple[float, ...]:
    if not all(math.isfinite(v) for v in values):
        raise ValueError("every entry must be a finite number")
    return values


class ModelTable(_Table):
    """``[model]``: the URDF (and optional SRDF) or the MJCF the robot is built from."""

    source: Literal["example-robot-data", "file"] = "example-robot-data"
    # inside example-robot-data's robots/ (source "example-robot-data") or a path
    urdf: str | None = None
    mjcf: str | None = None  # an MJCF model (MuJoCo XML): same rule as urdf; exclusive with urdf
    srdf: str | None = None  # same rule as urdf
    reference_posture: str | None = None  # a <group_state> of the SRDF, or a <key> of the MJCF

    @field_validator("urdf")
    @classmethod
    def _urdf_suffix(cls, v: str | None) -> str | None:
        if v is None:
            return v
        if v.lower().endswith((".xml", ".mjcf")):
            raise ValueError(
                "expected a URDF file (.urdf); an MJCF model (MuJoCo XML) goes in model.mjcf"
            )
        if not v.lower().endswith(".urdf"):
            raise ValueError("expected a URDF file (.urdf)")
        return v

    @field_validator("mjcf")
    @classmethod
    def _mjcf_suffix(cls, v: str | None) -> str | None:
        if v is not None and not v.lower().endswith((".xml", ".mjcf")):
            raise ValueError("expected an MJCF file (MuJoCo XML, .xml); a URDF goes in model.urdf")
        return v

    @model_validator(mode="after")
    def _one_model(self) -> ModelTable:
        if (self.urdf is None) == (self.mjcf is None):
            given = "both" if self.urdf is not None else "neither"
            raise ValueError(
                f"model.urdf and model.mjcf: {given} given; expected exactly one of them "
                "(a URDF path or an MJCF path)"
            )
        return self

    @model_validator(mode="after")
    def _posture_needs_srdf(self) -> ModelTable:
        if self.reference_posture is not None and self.srdf is None and self.mjcf is None:
            raise ValueError(
                f"model.reference_posture = {self.reference_posture!r}: needs model.srdf "
                "(the SRDF whose <group_state> it names)"
            )
        return self


class FootTable(_Table):
    """``[feet.left]`` / ``[feet.right]``: a sole rectangle attached to a link."""

    link: str  # URDF link the sole is attached to
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # sole centre in the link frame, m
    size: tuple[float, float]  # length (x), width (y) of the support rectangle, m

    @field_validator("offset")
    @classmethod
    def _offset_finite(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        return _finite(v)  # type: ignore[return-value]

    @field_validator("size")
    @classmethod
    def _size_positive(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not all(math.isfinite(x) and 0.01 <= x <= 1.0 for x in v):
            raise ValueError("expected [length, width] in m, each in 0.01–1.0")
        return v


class FeetTable(_Table):
    left: FootTable
    right: FootTable

    @model_validator(mode="after")
    def _same_size(self) -> FeetTable:
        if self.left.size != self.right.size:
            raise ValueError(
                f"feet.right.size = {list(self.right.size)}: expected the same size as "
                f"feet.left.size = {list(self.left.size)} (one sole rectangle for both feet)"
            )
        return self


class JointsTable(_Table):
    """``[joints]``: the leg joints are found from the feet; ``keep`` actuates more joints,
    ``lock`` lists joints locked at the posture (default: every joint not kept)."""

    keep: tuple[str, ...] = ()
    lock: tuple[str, ...] | None = None


class StandingTable(_Table):
    """``[standing]``: the nominal standing posture."""

    # solve the posture for this CoM height above the soles (m); default: the reference posture's
    com_height_m: float | None = Field(None, gt=0.1, le=3.0)


class ActuatorsTable(_Table):
    """``[actuators]``: joint properties a URDF does not carry (defaults scale with the mass),
    and torque limits that replace the model's (a URDF's ``<limit effort>``, an MJCF's
    ``actuatorfrcrange`` or motor): ``torque_limits`` per actuated joint (N m), then every
    actuated joint's limit times ``torque_scale``.  The whole-body QP, MuJoCo's motors and the
    derived numbers (the standing posture's torque check) all use the result."""

    armature: float | None = Field(None, ge=0.0, le=10.0)  # kg m², reflected rotor inertia
    damping: float | None = Field(None, ge=0.0, le=100.0)  # N m s/rad, viscous
    torque_limits: dict[str, float] = Field(default_factory=dict)  # joint → N m
    torque_scale: float = Field(1.0, gt=0.0, le=100.0)

    @field_validator("torque_limits")
    @classmethod
    def _torques(cls, v: dict[str, float]) -> dict[str, float]:
        for name, nm in v.items():
            if not (math.isfinite(nm) and 0.0 < nm <= 10_000.0):
                raise ValueError(f"{name} = {nm}: expected a torque limit in (0, 10000] N m")
        return v


class WalkingTable(_Table):
    """``[walking]``: numbers the loader derives; a value given here replaces the derived one
    (both are reported).  Units: m, m/s."""

    com_height_m: float | None = Field(None, gt=0.1, le=3.0)
    min_com_height_m: float | None = Field(None, gt=0.1, le=3.0)
    max_com_height_m: float | None = Field(None, gt=0.1, le=3.0)
    foot_spacing_m: float | None = Field(None, gt=0.0, le=2.0)
    max_step_length_m: float | None = Field(None, gt=0.0, le=2.0)
    max_step_width_m: float | None = Field(None, gt=0.0, le=2.0)
    min_step_width_m: float | None = Field(None, gt=0.0, le=2.0)
    max_step_height_m: float | None = Field(None, ge=0.0, le=1.0)
    max_swing_speed_m_s: float | None = Field(None, gt=0.0, le=20.0)
    mass_kg: float | None = Field(None, gt=0.0, le=1000.0)
    max_turn_rad: float | None = Field(None, gt=0.0, le=0.5)
    leg_length_m: float | None = Field(None, gt=0.0, le=3.0)  # hip–ankle at max_com_height_m

    @model_validator(mode="after")
    def _ordered(self) -> WalkingTable:
        lo, hi = self.min_com_height_m, self.max_com_height_m
        if lo is not None and hi is not None and lo >= hi:
            raise ValueError(
                f"walking.min_com_height_m = {lo}: expected < walking.max_com_height_m = {hi}"
            )
        lo, hi = self.min_step_width_m, self.max_step_width_m
        if lo is not None and hi is not None and lo >= hi:
            raise ValueError(
                f"walking.min_step_width_m = {lo}: expected < walking.max_step_width_m = {hi}"
            )
        return self


class RobotFile(_Table):
    """A whole robot file, validated; paths are resolved (absolute) by :func:`load_robot_file`."""

    name: str = Field(min_length=1, max_length=64)
    description: str = ""
    model: ModelTable
    posture: dict[str, float] = {}  # joint -> angle (rad), over the SRDF's reference posture
    joints: JointsTable = JointsTable()
    feet: FeetTable
    bodies: dict[str, str] = Field(min_length=1)  # push target name -> URDF link
    standing: StandingTable = StandingTable()
    actuators: ActuatorsTable = ActuatorsTable()
    walking: WalkingTable = WalkingTable()
    controller: dict[str, float | bool] = {}  # whole-body QP gains (dcmviz.sim.wbc.Gains fields)
    path: str = ""  # the file this was read from (set by the loader)
    urdf_path: str = ""  # absolute (set by the loader); "" for an MJCF model
    mjcf_path: str = ""  # absolute (set by the loader); "" for a URDF model
    srdf_path: str | None = None  # absolute (set by the loader)

    @property
    def model_path(self) -> str:
        """The model file (URDF or MJCF), absolute."""
        return self.mjcf_path or self.urdf_path

    @property
    def model_key(self) -> str:
        """``model.urdf`` or ``model.mjcf``: the key that names the model file."""
        return "model.mjcf" if self.model.mjcf is not None else "model.urdf"

    @field_validator("posture")
    @classmethod
    def _posture_finite(cls, v: dict[str, float]) -> dict[str, float]:
        for joint, angle in v.items():
            if not math.isfinite(angle):
                raise ValueError(f"{joint} = {angle}: expected a finite angle (rad)")
        return v

    @field_validator("controller")
    @classmethod
    def _known_gains(cls, v: dict[str, float | bool]) -> dict[str, float | bool]:
        if not v:  # importing the controller's gains loads MuJoCo and Pinocchio: only if needed
            return v
        from dataclasses import fields

        from dcmviz.robots.gains import Gains

        allowed = {f.name for f in fields(Gains)}
        for key in v:
            if key not in allowed:
                raise ValueError(
                    f"{key}: unknown gain; expected one of {', '.join(sorted(allowed))}"
                )
        return v


def _format(err: ValidationError) -> str:
    lines = []
    for e in err.errors():
        key = ""
        for part in e["loc"]:
            key += f"[{part}]" if isinstance(part, int) else (f".{part}" if key else str(part))
        msg = e["msg"].removeprefix("Value error, ")
        if not key:
            lines.append(msg)
        elif e["type"] == "missing":
            lines.append(f"{key}: missing; expected it (see {ROBOTS_DOC})")
        elif e["type"] == "extra_forbidden":
            lines.append(f"{key}: unknown key; check the spelling against {ROBOTS_DOC}")
        else:
            lines.append(f"{key} = {e.get('input')!r}: {msg}")
    return "; ".join(lines)


def is_robot_path(model: str) -> bool:
    """True if ``robot.model`` names a file rather than a built-in robot."""
    return model not in BUILTIN_ROBOTS


def builtin_path(name: str) -> Path:
    return DATA_DIR / f"{name}.toml"


def resolve_robot_path(model: str) -> str:
    """The robot file of ``robot.model``: a built-in name or a path (absolute or relative to the
    working directory) → absolute path; RobotFileError if there is none."""
    if model in BUILTIN_ROBOTS:
        return str(builtin_path(model))
    path = Path(model).expanduser()
    if path.suffix.lower() != ".toml":
        raise RobotFileError(
            f"unknown robot; expected a built-in robot ({', '.join(BUILTIN_ROBOTS)}) "
            f"or the path of a robot file (.toml, see {ROBOTS_DOC})"
        )
    if not path.is_file():
        raise RobotFileError(
            f"robot file not found (expected a built-in robot: {', '.join(BUILTIN_ROBOTS)}, "
            "or an existing .toml file; relative paths start at the working directory)"
        )
    return str(path.resolve())


def _model_path(file: Path, table: ModelTable, value: str, key: str) -> str:
    if table.source == "example-robot-data":
        path = Path(example_robot_data_dir()) / value
        where = "inside example-robot-data's robots/ directory"
    else:
        path = Path(value).expanduser()
        if not path.is_absolute():
            path = file.parent / path
        where = "relative to the robot file"
    if not path.is_file():
        raise RobotFileError(f"{file.name}: {key} = {value!r}: file not found ({where}: {path})")
    return str(path.resolve())


def parse_robot_file(path: str | Path) -> RobotFile:
    """Read and validate a robot file (TOML) without building its model; paths resolved."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise RobotFileError(f"robot file {str(path)!r} does not exist") from None
    if len(raw) > MAX_ROBOT_FILE_BYTES:
        raise RobotFileError(f"{path.name}: {len(raw)} bytes; at most {MAX_ROBOT_FILE_BYTES}")
    try:
        data: dict[str, Any] = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise RobotFileError(f"{path.name}: not valid TOML: {err}") from None
    for key in ("path", "urdf_path", "mjcf_path", "srdf_path"):
        if key in data:
            raise RobotFileError(f"{path.name}: {key}: unknown key (set by the loader)")
    try:
        robot = RobotFile.model_validate(data)
    except ValidationError as err:
        raise RobotFileError(f"{path.name}: {_format(err)}") from None
    urdf = (
        ""
        if robot.model.urdf is None
        else _model_path(path, robot.model, robot.model.urdf, "model.urdf")
    )
    mjcf = (
        ""
        if robot.model.mjcf is None
        else _model_path(path, robot.model, robot.model.mjcf, "model.mjcf")
    )
    srdf = (
        None
        if robot.model.srdf is None
        else _model_path(path, robot.model, robot.model.srdf, "model.srdf")
    )
    return robot.model_copy(
        update={
            "path": str(path.resolve()),
            "urdf_path": urdf,
            "mjcf_path": mjcf,
            "srdf_path": srdf,
        }
    )
