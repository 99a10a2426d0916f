"""``python -m dcmviz.robots NAME|PATH``: what a robot file derives, what it pins, its limits."""

from __future__ import annotations

from dcmviz.robots.model import RobotModel


def report(rm: RobotModel) -> str:
    """What was derived on load, what the file pins, and the limits (plain text)."""
    d, s, rf = rm.derived, rm.spec, rm.file
    lines = [
        f"{rf.name}: {rf.description}".rstrip(": "),
        f"  file {rf.path}",
        f"  model {rf.model_path}" + (f" (SRDF {rf.srdf_path})" if rf.srdf_path else ""),
        f"  legs: {', '.join(rm.legs['left'])} | {', '.join(rm.legs['right'])}",
        f"  kept: {', '.join(rf.joints.keep) or '-'}; locked: {len(rm.locked)} joints",
        f"  armature {rm.armature:.4g} kg m², damping {rm.damping:.4g} N m s/rad",
        f"  hip → sole {d.hip_sole_m:.3f} m; CoM {d.straight_com_height_m:.3f} m above the "
        "soles with straight legs",
        f"  standing: hip (roll) {d.hip_below_com_m:.3f} m below the CoM, ankle (pitch) "
        f"{d.ankle_above_sole_m:.3f} m above the sole",
        f"  lowest CoM stops at: {d.min_height_reason}",
        f"  longest step stops at: {d.stride_reason}",
        f"  hip yaw joints: {', '.join(d.hip_yaw) or '(none)'}",
    ]
    rows = (
        ("mass_kg", "kg"),
        ("com_height_m", "m"),
        ("min_com_height_m", "m"),
        ("max_com_height_m", "m"),
        ("foot_spacing_m", "m"),
        ("max_step_length_m", "m"),
        ("max_step_width_m", "m"),
        ("min_step_width_m", "m"),
        ("max_step_height_m", "m"),
        ("max_swing_speed_m_s", "m/s"),
        ("max_turn_rad", "rad"),
        ("leg_length_m", "m"),
    )
    for key, unit in rows:
        used, derived = getattr(s, key), getattr(d, key)
        pinned = getattr(rf.walking, key) is not None
        note = f"   (pinned; derived {derived:.3f})" if pinned else ""
        lines.append(f"  {key:22s} {used:8.3f} {unit}{note}")
    lo, hi = s.b_range_text()
    lines.append(f"  b range {lo}–{hi} s (nominal {s.b_nominal_s:.3f} s)")
    lines.append(
        f"  feet {s.foot_length_m:.3f} × {s.foot_width_m:.3f} m; bodies: "
        + ", ".join(f"{k}→{v}" for k, v in s.bodies.items())
    )
    lines.append("  joint            range [rad]        torque [N m]  speed [rad/s]")
    for name, lim in rm.limits.items():
        lines.append(
            f"  {name:16s} [{lim.lower_rad:+.2f}, {lim.upper_rad:+.2f}]  {lim.torque_nm:10.1f}"
            f"  {lim.velocity_rad_s:8.2f}"
        )
    return "\n".join(lines)
