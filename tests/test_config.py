"""Preset schema: round-trips, shipped presets, overrides, and errors that name the key."""

import math
from pathlib import Path

import pytest

from dcmviz import GRAVITY
from dcmviz.config import (
    Config,
    ConfigError,
    apply_overrides,
    config_from_dict,
    dumps_preset,
    field_info,
    load_preset,
    loads_preset,
    save_preset,
)
from dcmviz.robots import BUILTIN_ROBOTS, load_robot

PRESETS = sorted(Path(__file__).parents[1].joinpath("presets").glob("*.toml"))


def test_presets_exist():
    names = {p.stem for p in PRESETS}
    assert {"walk_forward", "stand_walk_stand", "lateral_push", "tug_of_war", "stairs"} <= names


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_every_preset_loads_and_round_trips(path, tmp_path):
    config = load_preset(path)
    out = tmp_path / "again.toml"
    save_preset(config, out)
    assert load_preset(out) == config
    assert loads_preset(dumps_preset(config)) == config


def test_round_trip_with_explicit_footsteps_and_pushes(tmp_path):
    data = {
        "name": "custom",
        "gait": {
            "footsteps": [
                {"side": "left", "position": [0.21, 0.0851, 0.0], "yaw": 0.1},
                {"side": "right", "position": [0.4, -0.09, 0.0]},
            ]
        },
        "pushes": [{"start": 1.25, "duration": 0.2, "force": [10.5, -3.25, 0.0], "ramp": 0.1}],
    }
    config = config_from_dict(data)
    save_preset(config, tmp_path / "c.toml")
    again = load_preset(tmp_path / "c.toml")
    assert again == config
    assert again.gait.footsteps[0].position == (0.21, 0.0851, 0.0)


def test_defaults_match_design_schema():
    c = Config()
    assert (c.gait.n_steps, c.gait.step_length, c.gait.t_ss, c.gait.t_ds) == (10, 0.20, 0.7, 0.2)
    assert (c.dcm.order, c.dcm.b, c.control.k_xi, c.control.k_f) == (5, 0.30, 3.0, 10.0)


@pytest.mark.parametrize(
    ("data", "words"),
    [
        ({"gait": {"t_ss": -0.7}}, ["gait.t_ss", "-0.7", "greater than"]),
        ({"gait": {"t_ds": 0.0}}, ["gait.t_ds", "0.0"]),
        ({"dcm": {"order": 2}}, ["dcm.order", "2", "0, 1, 3 or 5"]),
        ({"dcm": {"b": 0.0}}, ["dcm.b", "0.0"]),
        ({"robot": {"model": "atlas"}}, ["robot.model", "atlas", "talos", "g1"]),
        ({"gait": {"n_step": 3}}, ["gait.n_step", "unknown key"]),
        ({"gait": {"n_steps": "ten"}}, ["gait.n_steps", "ten"]),
        ({"gait": {"step_length": 0.48}}, ["gait.step_length", "0.48", "reach"]),
        ({"gait": {"step_width": 0.08}}, ["gait.step_width", "collide"]),
        ({"pushes": [{"body": "head"}]}, ["pushes[0].body", "head", "torso"]),
        ({"pushes": [{"force": [0, float("nan"), 0]}]}, ["pushes[0].force", "finite"]),
        ({"pushes": [{"duration": 1.0, "ramp": 2.0}]}, ["ramp", "duration"]),
        ({"sim": {"duration": 0}}, ["sim.duration", "0"]),
        (
            {"gait": {"footsteps": [{"side": "left", "position": [0.9, 0.1, 0.0]}]}},
            ["gait.footsteps[0]", "reach"],
        ),
        (
            {"gait": {"footsteps": [{"side": "left", "position": [0.1, -0.2, 0.0]}]}},
            ["gait.footsteps[0]", "across"],
        ),
        (
            {
                "gait": {
                    "footsteps": [
                        {"side": "left", "position": [0.1, 0.1, 0.0]},
                        {"side": "left", "position": [0.2, 0.1, 0.0]},
                    ]
                }
            },
            ["footsteps[1].side", "alternate"],
        ),
    ],
)
def test_bad_values_name_key_value_and_allowed(data, words):
    with pytest.raises(ConfigError) as err:
        config_from_dict(data)
    message = str(err.value)
    for word in words:
        assert word in message, message


def test_bad_toml_and_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not valid TOML"):
        loads_preset("name = ")
    with pytest.raises(ConfigError, match="does not exist"):
        load_preset(tmp_path / "nope.toml")
    with pytest.raises(ConfigError, match="bytes"):
        loads_preset("# " + "x" * 70000)


def test_overrides_use_toml_literals():
    c = apply_overrides(Config(), ["control.observer=false", "dcm.b=0.25", 'robot.model="g1"'])
    assert (c.control.observer, c.dcm.b, c.robot.model) == (False, 0.25, "g1")
    for bad, word in [
        ("dcm.b", "section.key=value"),
        ("b=0.3", "section.key"),
        ("dcm.b=abc", "TOML literal"),
        ("foo.b=1", "unknown section"),
        ("dcm.bb=1", "dcm.bb"),
    ]:
        with pytest.raises(ConfigError, match=word):
            apply_overrides(Config(), [bad])


def test_config_is_immutable_and_replace_validates():
    c = Config()
    with pytest.raises(Exception):  # noqa: B017 - pydantic's frozen error
        c.gait.n_steps = 3
    assert c.replace(gait={**c.gait.model_dump(), "n_steps": 3}).gait.n_steps == 3
    with pytest.raises(ConfigError, match="gait.n_steps"):
        c.replace(gait={**c.gait.model_dump(), "n_steps": 0})


def test_field_info_for_gui_labels():
    info = field_info("gait", "t_ss")
    assert info["symbol"] == "T_ss" and info["unit"] == "s" and info["gt"] == 0.1
    assert field_info("dcm", "b")["ge"] == 0.15


def test_b_outside_the_robots_heights_is_refused_with_height_and_ranges():
    with pytest.raises(ConfigError) as err:
        config_from_dict({"dcm": {"b": 0.33}})
    assert str(err.value) == (
        "dcm.b = 0.33: asks for a CoM height of 1.068 m; talos walks at 0.720–0.900 m, "
        "i.e. b from 0.271 to 0.302 s"
    )
    for robot, b in (("talos", 0.26), ("g1", 0.30), ("g1", 0.2)):
        with pytest.raises(ConfigError) as err:
            config_from_dict({"robot": {"model": robot}, "dcm": {"b": b}})
        message = str(err.value)
        for word in ("dcm.b", f"{b}", f"{GRAVITY * b * b:.3f} m", robot, "walks at", "b from"):
            assert word in message, message


@pytest.mark.parametrize("robot", sorted(BUILTIN_ROBOTS))
def test_b_range_follows_the_robots_com_heights(robot):
    spec = load_robot(robot).spec
    lo, hi = spec.b_range_s
    # Δz_vrp = g b² is the CoM height (eq. 1): the ends of b's range give the ends of the heights
    assert GRAVITY * lo**2 == pytest.approx(spec.min_com_height_m, abs=1e-12)
    assert GRAVITY * hi**2 == pytest.approx(spec.max_com_height_m, abs=1e-12)
    assert spec.min_com_height_m < spec.com_height_m < spec.max_com_height_m
    assert lo < spec.b_nominal_s < hi
    # a gait within the robot's reach (Romeo's steps end at 0.18 m)
    gait = {"step_length": min(0.2, spec.max_step_length_m), "step_width": spec.foot_spacing_m}
    for b in (lo, hi, spec.b_nominal_s):  # a b control over this range never offers a refused b
        assert (
            config_from_dict({"robot": {"model": robot}, "gait": gait, "dcm": {"b": b}}).dcm.b == b
        )
    for b in (lo - 1e-4, hi + 1e-4):
        with pytest.raises(ConfigError, match="dcm.b"):
            config_from_dict({"robot": {"model": robot}, "gait": gait, "dcm": {"b": b}})


@pytest.mark.parametrize("path", PRESETS, ids=lambda p: p.stem)
def test_every_presets_b_is_a_height_its_robot_walks_at(path):
    config = load_preset(path)
    spec = load_robot(config.robot.model).spec
    assert spec.min_com_height_m <= GRAVITY * config.dcm.b**2 <= spec.max_com_height_m


def test_turning_that_pivots_out_of_reach_is_refused():
    # Δx = L + w tan(|turn|/2) in the stance foot's frame: 0.45 + 0.17 tan(0.15) > 0.45
    with pytest.raises(ConfigError) as err:
        config_from_dict({"gait": {"step_length": 0.45, "turn": 0.3}})
    dx = 0.45 + 0.17 * math.tan(0.15)
    for word in ("gait.step_length", "gait.turn", f"{dx:.3f}", "0.45 m"):
        assert word in str(err.value), str(err.value)
    assert config_from_dict({"gait": {"step_length": 0.40, "turn": 0.3}}).gait.turn == 0.3


def test_replace_with_a_dict_changes_only_the_keys_it_names():
    """A dict changes the keys it names and keeps the rest of the section (a preset's gains,
    the observer switched off before a strategy is picked); a model or a list replaces the
    whole entry.  Before, a dict replaced its whole section with defaults for the keys it left
    out (the observer came back on in tests/test_sweep_bounds.py)."""
    preset = load_preset(Path(__file__).parents[1] / "presets" / "g1_walk.toml")
    off = preset.replace(control={"observer": False})
    picked = off.replace(control={"recovery": "multi_step_timing"})
    assert (off.control.observer, picked.control.observer) == (False, False)
    assert picked.control.recovery == "multi_step_timing"
    changed = {k for k, v in picked.control.model_dump().items()
               if v != preset.control.model_dump()[k]}  # fmt: skip
    assert changed == {"observer", "recovery"}
    assert picked.gait == preset.gait and picked.robot == preset.robot  # untouched sections
    longer = preset.replace(gait={"n_steps": preset.gait.n_steps + 2})
    assert longer.gait.step_length == preset.gait.step_length != Config().gait.step_length
    assert longer.gait.n_steps == preset.gait.n_steps + 2
    assert preset.replace(control=Config().control).control == Config().control  # a model: whole
    assert not preset.replace(pushes=[]).pushes
    with pytest.raises(ConfigError, match="gait.n_steps"):
        preset.replace(gait={"n_steps": 0})
