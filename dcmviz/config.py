"""Preset schema (docs/presets.md), TOML load/save and validation.

A :class:`Config` is immutable and validated as a whole; every entry point (dashboard, runner,
sweep, tests) goes through :func:`load_preset` / :func:`config_from_dict`.  Errors name the key,
the bad value and what is allowed::

    ConfigError: gait.t_ss = -0.7: must be > 0.1 (single-support duration, s)

Field metadata (``symbol``, ``unit``, ``description``, bounds) is read by the dashboard to label
its controls, so a control and the schema can never disagree about a range.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, Literal

import tomli_w
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from dcmviz.robots import BUILTIN_ROBOTS, RobotFileError, load_robot
from dcmviz.robots.reach import check_reachable

MAX_PRESET_BYTES = 64 * 1024  # presets are small; larger uploads are refused
PRESETS_DOC = "docs/presets.md"  # the preset schema, for users (errors point there)


class ConfigError(ValueError):
    """A preset or override is invalid; the message names each bad key, value and what is allowed."""


def _field(default: Any, *, symbol: str = "", unit: str = "", description: str = "", **bounds):
    return Field(
        default,
        description=description,
        json_schema_extra={"symbol": symbol, "unit": unit},
        **bounds,
    )


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


class PresetFootstep(_Section):
    """One explicit footstep of a preset (``[[gait.footsteps]]``)."""

    side: Literal["left", "right"]
    position: tuple[float, float, float]
    yaw: float = _field(
        0.0, symbol="ψ", unit="rad", description="sole yaw", ge=-math.pi, le=math.pi
    )

    @field_validator("position")
    @classmethod
    def _finite(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if not all(math.isfinite(c) for c in v):
            raise ValueError("every coordinate must be a finite number (m)")
        return v


class RobotSection(_Section):
    model: str = _field(
        "talos",
        description="a built-in robot (talos, g1, romeo) or the path of a robot file "
        "(docs/robots.md)",
    )

    @field_validator("model")
    @classmethod
    def _robot_file_loads(cls, v: str) -> str:
        try:
            load_robot(v)  # the whole robot file is checked: nothing half-loads
        except RobotFileError as err:
            raise ValueError(str(err).removeprefix(f"robot.model = {v!r}: ")) from None
        return v


class GaitSection(_Section):
    mode: Literal["plan", "continuous"] = _field(
        "plan", description="plan: stand → n_steps → stand; continuous: receding horizon"
    )
    n_steps: int = _field(10, symbol="n", unit="", description="number of steps", ge=1, le=200)
    step_length: float = _field(
        0.20, symbol="Δx", unit="m", description="forward distance per step", ge=-0.5, le=0.5
    )
    step_width: float = _field(
        0.17, symbol="w", unit="m", description="lateral distance between the feet", ge=0.05, le=0.6
    )
    step_height: float = _field(
        0.0, symbol="Δz", unit="m", description="height change per step (stairs)", ge=-0.2, le=0.2
    )
    turn: float = _field(0.0, symbol="Δψ", unit="rad", description="yaw per step", ge=-0.5, le=0.5)
    t_ss: float = _field(0.7, symbol="T_ss", unit="s", description="single support", gt=0.1, le=3.0)
    t_ds: float = _field(
        0.2, symbol="T_ds", unit="s", description="double support (transfer)", gt=0.02, le=2.0
    )
    t_start: float = _field(
        1.0,
        symbol="T_start",
        unit="s",
        description="standing → first single support",
        gt=0.1,
        le=5.0,
    )
    t_stop: float = _field(
        1.0, symbol="T_stop", unit="s", description="last step → standing", gt=0.1, le=5.0
    )
    first_swing: Literal["left", "right"] = "left"
    footsteps: tuple[PresetFootstep, ...] | None = None

    @field_validator("footsteps")
    @classmethod
    def _alternate(cls, v: tuple[PresetFootstep, ...] | None) -> tuple[PresetFootstep, ...] | None:
        if v is None:
            return v
        if len(v) == 0:
            raise ValueError("give at least one footstep or leave the list out")
        for i in range(1, len(v)):
            if v[i].side == v[i - 1].side:
                raise ValueError(
                    f"footsteps[{i}].side = {v[i].side!r}: sides must alternate "
                    f"(footsteps[{i - 1}] is {v[i - 1].side!r} too)"
                )
        return v


class DcmSection(_Section):
    order: Literal[0, 1, 3, 5] = _field(
        5, symbol="n_poly", description="VRP polynomial order, Table I"
    )
    b: float = _field(
        0.30, symbol="b", unit="s", description="DCM time constant; Δz_vrp = g b²", ge=0.15, le=0.6
    )


class ControlSection(_Section):
    k_xi: float = _field(
        3.0, symbol="k_ξ", unit="1/s", description="DCM gain, K_ξ = k_ξ I", gt=0.0, le=20.0
    )
    step_adjustment: bool = _field(True, description="analytical step adjustment, eqs. 27–35")
    max_step_adjustment: float = _field(
        0.3,
        symbol="|Δv_adj|max",
        unit="m",
        description="reach limit of an adjusted footstep",
        ge=0.0,
        le=1.0,
    )
    recovery: Literal["next_step", "multi_step", "multi_step_timing", "crossover"] = _field(
        "next_step",
        description=(
            "next_step: the paper's adjustment of the next footstep (eqs. 27–35); multi_step: "
            "the next three footsteps share the DCM error through one QP on the same maps, "
            "bounded by what the CoP can still do; multi_step_timing: the same, and the present "
            "and next two phases may end earlier or later; crossover: the same, and the recovery "
            "footstep may cross the stance foot (in front or behind) within the robot's reach"
        ),
    )
    observer: bool = _field(True, description="momentum-based disturbance observer, eqs. 42–49")
    k_f: float = _field(
        10.0, symbol="k_F", unit="1/s", description="observer gain", gt=0.0, le=200.0
    )


class SimSection(_Section):
    backend: Literal["mujoco", "lip"] = _field("mujoco", description="humanoid or point mass")
    duration: float = _field(
        20.0, symbol="T_sim", unit="s", description="headless run length", gt=0.0, le=3600.0
    )


class Push(_Section):
    start: float = _field(3.0, symbol="t_0", unit="s", description="push start", ge=0.0)
    duration: float = _field(
        1.0, symbol="T_push", unit="s", description="push length", gt=0.0, le=600.0
    )
    force: tuple[float, float, float] = (0.0, 25.0, 0.0)
    ramp: float = _field(0.0, symbol="T_ramp", unit="s", description="linear ramp-up", ge=0.0)
    body: str = "torso"

    @field_validator("force")
    @classmethod
    def _force(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if not all(math.isfinite(c) for c in v):
            raise ValueError("every component must be a finite number (N)")
        if math.sqrt(sum(c * c for c in v)) > 5000.0:
            raise ValueError("magnitude must be ≤ 5000 N")
        return v

    @model_validator(mode="after")
    def _ramp_fits(self) -> Push:
        if self.ramp > self.duration:
            raise ValueError(f"ramp = {self.ramp}: must be ≤ duration ({self.duration} s)")
        return self

    def force_at(self, t: float) -> tuple[float, float, float]:
        """World-frame force (N) at time t: a linear ramp over ``ramp`` s, then held."""
        if t < self.start or t >= self.start + self.duration:
            return (0.0, 0.0, 0.0)
        s = 1.0 if self.ramp <= 0.0 else min(1.0, (t - self.start) / self.ramp)
        return (s * self.force[0], s * self.force[1], s * self.force[2])


class StairsSection(_Section):
    """``[terrain.stairs]``: a flight of stairs along +x (up, or down with a negative rise)."""

    start: float = _field(
        0.35, symbol="x_0", unit="m", description="x of the first riser", ge=-20.0, le=20.0
    )
    rise: float = _field(
        0.10, symbol="h_rise", unit="m", description="height per step (< 0: down)", ge=-0.3, le=0.3
    )
    run: float = _field(0.30, symbol="l_run", unit="m", description="tread depth", ge=0.15, le=1.0)
    count: int = _field(5, symbol="n_stairs", description="number of steps", ge=1, le=30)
    width: float = _field(1.2, unit="m", description="lateral extent", ge=0.3, le=10.0)
    landing: float = _field(
        1.5, unit="m", description="landing beyond the last step (down: behind the first)",
        ge=0.3, le=20.0,
    )  # fmt: skip

    @field_validator("rise")
    @classmethod
    def _not_flat(cls, v: float) -> float:
        if v == 0.0:
            raise ValueError("must not be 0 (no stairs: leave [terrain.stairs] out)")
        return v


class BoxEntry(_Section):
    """``[[terrain.boxes]]``: a platform or stepping stone standing on the floor."""

    center: tuple[float, float]  # m, x, y of the top face's centre
    size: tuple[float, float]  # m, extent along the box's x and y
    top: float = _field(0.1, unit="m", description="height of the top face", gt=0.0, le=2.0)
    yaw: float = _field(0.0, unit="rad", description="yaw", ge=-math.pi, le=math.pi)

    @field_validator("center", "size")
    @classmethod
    def _finite_positive(cls, v: tuple[float, float], info: Any) -> tuple[float, float]:
        if not all(math.isfinite(c) for c in v):
            raise ValueError("every coordinate must be a finite number (m)")
        if info.field_name == "size" and not all(0.05 <= c <= 20.0 for c in v):
            raise ValueError("each side must be 0.05–20 m")
        return v


class TerrainSection(_Section):
    """``[terrain]``: stairs and boxes on the flat floor; footsteps take the height under them."""

    stairs: StairsSection | None = None
    boxes: tuple[BoxEntry, ...] = Field(default=(), max_length=200)


class Config(_Section):
    name: str = "Walk forward"
    description: str = ""
    robot: RobotSection = RobotSection()
    gait: GaitSection = GaitSection()
    dcm: DcmSection = DcmSection()
    control: ControlSection = ControlSection()
    sim: SimSection = SimSection()
    pushes: tuple[Push, ...] = ()
    terrain: TerrainSection | None = None

    @model_validator(mode="after")
    def _robot_consistent(self) -> Config:
        spec = load_robot(self.robot.model).spec
        for i, push in enumerate(self.pushes):
            if push.body not in spec.bodies:
                raise ValueError(
                    f"pushes[{i}].body = {push.body!r}: unknown body for {spec.name}; "
                    f"allowed: {', '.join(spec.bodies)}"
                )
        problem = spec.height_problem(self.dcm.b)
        if problem:
            raise ValueError(f"dcm.b = {self.dcm.b}: {problem}")
        check_reachable(spec, self.gait)
        if self.terrain is not None and self.gait.step_height != 0.0:
            raise ValueError(
                f"gait.step_height = {self.gait.step_height}: must be 0 with a [terrain] "
                "(each footstep takes the height of the ground under it)"
            )
        return self

    def replace(self, **sections: Any) -> Config:
        """A new validated Config with some sections changed: a dict changes the keys it names
        and keeps the section's others (``replace(control={"observer": False})`` keeps the
        preset's gains); a model, a list or a value replaces the whole entry.  (Before, a dict
        replaced its whole section, so every key it left out went back to its default: tests
        that turned the observer off and then picked a strategy ran with it on again.)"""
        data = self.to_dict()
        for key, value in sections.items():
            if isinstance(value, BaseModel):
                data[key] = value.model_dump()
            elif isinstance(value, dict) and isinstance(data.get(key), dict):
                data[key] = {**data[key], **value}
            else:
                data[key] = value
        return config_from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict in the TOML layout (None values dropped)."""
        return _drop_none(self.model_dump(mode="python"))


def _drop_none(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _drop_none(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, list | tuple):
        return [_drop_none(v) for v in obj]
    return obj


def _format_error(err: ValidationError) -> str:
    lines = []
    for e in err.errors():
        loc = e["loc"]
        key = ""
        for part in loc:
            key += f"[{part}]" if isinstance(part, int) else (f".{part}" if key else str(part))
        msg = e["msg"]
        if msg.startswith("Value error, "):
            msg = msg[len("Value error, ") :]
        if not key:  # model-level validator: the message already names the key
            lines.append(msg)
            continue
        value = e.get("input")
        shown = "(missing)" if e["type"] == "missing" else repr(value)
        if e["type"] == "extra_forbidden":
            lines.append(
                f"{key}: unknown key (value {shown}); check the spelling against the "
                f"preset schema in {PRESETS_DOC}"
            )
        else:
            lines.append(f"{key} = {shown}: {msg}")
    return "; ".join(lines)


def config_from_dict(data: dict[str, Any]) -> Config:
    """Validate a dict in the TOML layout; ConfigError names every bad key."""
    if not isinstance(data, dict):
        raise ConfigError(f"a preset must be a TOML table, got {type(data).__name__}")
    try:
        return Config.model_validate(data)
    except ValidationError as err:
        raise ConfigError(_format_error(err)) from None
    except ValueError as err:  # raised by a validator outside pydantic's wrapping
        raise ConfigError(str(err)) from None


def loads_preset(text: str) -> Config:
    """Parse and validate preset TOML text."""
    if len(text.encode()) > MAX_PRESET_BYTES:
        raise ConfigError(
            f"preset is {len(text.encode())} bytes; at most {MAX_PRESET_BYTES} allowed"
        )
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"not valid TOML: {err}") from None
    return config_from_dict(data)


def load_preset(path: str | Path) -> Config:
    """Load and validate a preset file (schema: docs/presets.md)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"preset file {str(path)!r} does not exist") from None
    except UnicodeDecodeError:
        raise ConfigError(f"preset file {str(path)!r} is not UTF-8 text") from None
    try:
        return loads_preset(text)
    except ConfigError as err:
        raise ConfigError(f"{path.name}: {err}") from None


def dumps_preset(config: Config) -> str:
    """TOML text that :func:`loads_preset` turns back into an equal Config."""
    return tomli_w.dumps(config.to_dict())


def save_preset(config: Config, path: str | Path) -> None:
    Path(path).write_text(dumps_preset(config), encoding="utf-8")


def apply_overrides(config: Config, overrides: list[str]) -> Config:
    """Apply ``section.key=value`` overrides (values are TOML literals), e.g. ``dcm.b=0.31``."""
    data = config.to_dict()
    for item in overrides:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected section.key=value, e.g. dcm.b=0.31")
        key, _, literal = item.partition("=")
        key = key.strip()
        parts = key.split(".")
        if len(parts) != 2 or not all(parts):
            raise ConfigError(f"--set {item!r}: the key must be section.key, e.g. control.k_xi")
        try:
            value = tomllib.loads(f"v = {literal.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            raise ConfigError(
                f"--set {item!r}: {literal!r} is not a TOML literal (strings need quotes: "
                f'robot.model="g1")'
            ) from None
        section, name = parts
        if section not in data or not isinstance(data[section], dict):
            allowed = [k for k, v in data.items() if isinstance(v, dict)]
            raise ConfigError(
                f"--set {item!r}: unknown section {section!r}; allowed: {', '.join(allowed)}"
            )
        data[section][name] = value
    return config_from_dict(data)


def field_info(section: str, name: str) -> dict[str, Any]:
    """Label metadata of one field (symbol, unit, description, bounds) for GUIs."""
    model = {
        "gait": GaitSection,
        "dcm": DcmSection,
        "control": ControlSection,
        "sim": SimSection,
        "robot": RobotSection,
    }[section]
    info = model.model_fields[name]
    extra = info.json_schema_extra or {}
    out: dict[str, Any] = {
        "symbol": extra.get("symbol", ""),
        "unit": extra.get("unit", ""),
        "description": info.description or "",
    }
    for meta in info.metadata:
        for bound in ("gt", "ge", "lt", "le"):
            if hasattr(meta, bound):
                out[bound] = getattr(meta, bound)
    return out


__all__ = [
    "BUILTIN_ROBOTS",
    "Config",
    "ConfigError",
    "ControlSection",
    "DcmSection",
    "PresetFootstep",
    "GaitSection",
    "Push",
    "RobotSection",
    "SimSection",
    "StairsSection",
    "BoxEntry",
    "TerrainSection",
    "apply_overrides",
    "config_from_dict",
    "dumps_preset",
    "field_info",
    "load_preset",
    "loads_preset",
    "save_preset",
]
