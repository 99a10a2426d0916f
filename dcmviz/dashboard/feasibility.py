"""What the robot cannot do in a plan, shown: a markdown block in the Plan tab, a compact line for
the status, and the likely cause of a fall.

The warnings come from :func:`dcmviz.gait.check_plan` (pure, about a millisecond); the plan view
marks the offending footsteps and waypoints in the 3-D scene (:func:`scene.draw_warnings`).
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import viser

from dcmviz.config import Config
from dcmviz.dashboard.aim import describe
from dcmviz.gait import GaitPlan, PlanWarning, check_plan
from dcmviz.robots import load_robot

SHOWN_WARNINGS = 6  # the panel lists this many, then "and n more"


def plan_warnings(plan: GaitPlan, config: Config) -> tuple[PlanWarning, ...]:
    """check_plan for ``config``'s robot; never raises (a checker bug is not the user's error)."""
    try:
        robot = load_robot(config.robot.model)
        return tuple(check_plan(plan, robot.spec, config, lambda: robot.crossover))
    except Exception as err:  # noqa: BLE001
        return (PlanWarning(f"feasibility check failed: {err!r}"),)


def warnings_markdown(warnings: Sequence[PlanWarning], source: str) -> str:
    """The Plan tab's block: every warning (the first few), or that the plan is feasible."""
    if not warnings:
        return f"<small>Feasible ({source}): every footstep and VRP waypoint within reach.</small>"
    n = len(warnings)
    lines = [
        f"<span style='color:#e61414'>**{n} feasibility warning{'s' * (n > 1)}**</span> ({source}):"
    ]
    lines += [f"- {w.message}" for w in warnings[:SHOWN_WARNINGS]]
    if len(warnings) > SHOWN_WARNINGS:
        lines.append(f"- … and {len(warnings) - SHOWN_WARNINGS} more")
    lines.append("\n<small>Marked red in the scene: offending footsteps and waypoints.</small>")
    return "\n".join(lines)


def compact(warnings: Sequence[PlanWarning]) -> str:
    """One line for the status: how many, and the settings to change."""
    if not warnings:
        return ""
    settings = sorted({w.setting for w in warnings if w.setting})
    what = f" ({', '.join(settings)})" if settings else ""
    n = len(warnings)
    return f"<span style='color:#e61414'>{n} feasibility warning{'s' * (n > 1)}</span>{what}"


def likely_cause(
    warnings: Sequence[PlanWarning],
    config: Config,
    push: tuple | None = None,
) -> str:
    """Why the robot probably fell: a push just before the fall first (the plan was walkable
    before it), then the plan's first warning, then what the settings suggest."""
    if push is not None:
        t, body, force = push[:3]
        what = "pull (a drag)" if len(push) > 3 and push[3] else "push"
        more = (
            f" (the plan also has {len(warnings)} feasibility warning"
            + f"{'s' * (len(warnings) > 1)})"
            if warnings
            else ""
        )
        return (
            f"likely cause: the {what} on the {body} at t = {t:.2f} s ({describe(force)}): more "
            f"than step adjustment could catch (a smaller |F| or T_push, or a larger "
            f"|Δv_adj|max){more}"
        )
    if warnings:
        first = main_warning(warnings).message
        more = f" (and {len(warnings) - 1} more warnings)" if len(warnings) > 1 else ""
        return f"likely cause: {first}{more}"
    spec = load_robot(config.robot.model).spec
    gait = config.gait
    if abs(gait.step_length) >= 0.9 * spec.max_step_length_m:
        return (
            f"likely cause: step length {gait.step_length} m at the reach limit "
            f"({spec.max_step_length_m} m)"
        )
    if not config.control.step_adjustment:
        return "likely cause: step adjustment is off (the DCM error grows unchecked)"
    return "no feasibility warning for this plan"


def main_warning(warnings: Sequence[PlanWarning]) -> PlanWarning:
    """The warning the walk meets first (a warning of the whole plan before any footstep's; on
    a tie, the one whose setting most warnings name): a fall early in a walk whose every step
    swings too fast is the swing's, not a late footstep's reach."""
    named = [w.setting for w in warnings if w.setting]

    def rank(w: PlanWarning) -> tuple[int, int]:
        return (w.step if w.step is not None else -1, -named.count(w.setting))

    return min(warnings, key=rank)


def setting_to_change(warnings: Sequence[PlanWarning], config: Config) -> str:
    """The setting to change after repeated falls without a push: the main warning's (the one
    the walk meets first), else the one the settings point at."""
    with_setting = [w for w in warnings if w.setting]
    if with_setting:
        return main_warning(with_setting).setting
    spec = load_robot(config.robot.model).spec
    if abs(config.gait.step_length) >= 0.9 * spec.max_step_length_m:
        return "gait.step_length"
    if not config.control.step_adjustment:
        return "control.step_adjustment"
    return "gait.t_ss"


class FeasibilityPanel:
    """The Plan tab's warning block; remembers the latest warnings for the status and faults."""

    def __init__(self, gui: viser.GuiApi) -> None:
        self.gui_warnings = gui.add_markdown("")
        self.warnings: tuple[PlanWarning, ...] = ()
        self.source = ""
        self._shown = (-1, False)  # (config version, walked) of what is shown
        self._lock = threading.Lock()

    def show(
        self, warnings: Sequence[PlanWarning], source: str, version: int, walked: bool
    ) -> None:
        """Show the warnings of config ``version``'s plan: the edit's (``walked`` False) until the
        walk has taken it, then the walked plan's, which an edit's of the same version never
        replaces (the two threads that call this may run in either order)."""
        text = warnings_markdown(warnings, source)
        with self._lock:
            if (version, walked) < self._shown:
                return
            self._shown = (version, walked)
            self.warnings, self.source = tuple(warnings), source
            if self.gui_warnings.content != text:
                self.gui_warnings.content = text

    def compact(self) -> str:
        return compact(self.warnings)
