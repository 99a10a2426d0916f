"""Automatic tuning: Ray Tune with an Optuna (TPE) search over the controller's gains and timing,
scored by the push-recovery envelope (or by DCM tracking under fixed pushes).

Searched (``section.key``: range), within what the robot and the preset schema allow:

* ``control.k_xi`` (1/s): 1 … 10, log scale; ``control.k_f`` (1/s): 2 … 50, log scale (only
  with the observer on);
* ``dcm.b`` (s): the robot's walkable range ``RobotSpec.b_range_s`` if it has one, else ±10 %
  of ``b_nominal_s``;
* ``gait.t_ss`` (s): 0.5 … 1.0; ``gait.t_ds`` (s): 0.1 … 0.3;
* ``control.max_step_adjustment`` (m): 0.1 … the robot's step length reach (only with step
  adjustment on).

Values are rounded to 4 significant digits before they are tried, so the written preset is
exactly what was measured.  Objectives (the preset's own controller flags):

* ``weakest`` (maximise, N·s): the smallest max impulse over the push directions;
* ``area`` (maximise, (N·s)²): the area of the envelope's polar polygon;
* ``tracking`` (minimise, m): the mean over directions of the largest DCM error |ξ − ξ_ref|
  during a walk with one push of ``probe_impulse_ns`` (a fall counts :data:`FALL_PENALTY_M`).

Trials run one at a time (Optuna's suggestions then depend only on the seed and the finished
trials, so a seed reproduces the search); each trial's rollouts are Ray tasks inside the trial's
placement group (one bundle per CPU), so all cores work on it.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from dcmviz.config import Config, ConfigError, config_from_dict, save_preset
from dcmviz.robots import load_robot
from dcmviz.sweep.experiments import (
    PRESET_CONTROLLER,
    Execution,
    SweepSettings,
    envelope,
    probe_cells,
    run,
)
from dcmviz.sweep.report import envelope_metric
from dcmviz.sweep.runner import RayRunner, ray_init

OBJECTIVES: dict[str, tuple[str, str]] = {  # name -> (mode, unit)
    "weakest": ("max", "N·s"),
    "area": ("max", "(N·s)²"),
    "tracking": ("min", "m"),
}
FALL_PENALTY_M = 1.0  # tracking objective: the DCM error counted for a fall (m)
SIGNIFICANT = 4  # digits kept of a suggested value


@dataclass(frozen=True)
class Param:
    """One searched preset key and its range."""

    key: str  # section.name
    low: float
    high: float
    log: bool = False
    unit: str = ""

    def round(self, value: float) -> float:
        return float(f"{value:.{SIGNIFICANT}g}")


def _inward(lo: float, hi: float) -> tuple[float, float]:
    """The range shrunk to values with SIGNIFICANT digits (so rounding stays inside)."""

    def step(v: float) -> float:
        return 10.0 ** (math.floor(math.log10(abs(v))) - SIGNIFICANT + 1)

    return math.ceil(lo / step(lo) - 1e-9) * step(lo), math.floor(hi / step(hi) + 1e-9) * step(hi)


def search_space(config: Config) -> list[Param]:
    """The searched keys for this preset and robot (see module doc)."""
    spec = load_robot(config.robot.model).spec
    b_range = getattr(spec, "b_range_s", None)
    if b_range is None:
        b_range = (0.9 * spec.b_nominal_s, 1.1 * spec.b_nominal_s)
    b_lo, b_hi = _inward(max(0.15, b_range[0]), min(0.6, b_range[1]))
    space = [
        Param("control.k_xi", 1.0, 10.0, log=True, unit="1/s"),
        Param("dcm.b", round(b_lo, 6), round(b_hi, 6), unit="s"),
        Param("gait.t_ss", 0.5, 1.0, unit="s"),
        Param("gait.t_ds", 0.1, 0.3, unit="s"),
    ]
    if config.control.observer:
        space.append(Param("control.k_f", 2.0, 50.0, log=True, unit="1/s"))
    if config.control.step_adjustment:
        high = _inward(0.1, spec.max_step_length_m)[1]
        space.append(Param("control.max_step_adjustment", 0.1, round(high, 6), unit="m"))
    return space


def apply_params(config: Config, params: dict[str, float], space: list[Param]) -> Config:
    """The preset with the searched keys set (rounded); ConfigError if that is not a valid
    preset (e.g. a b the robot cannot walk at)."""
    data = config.to_dict()
    for p in space:
        section, name = p.key.split(".")
        data[section][name] = p.round(float(params[p.key]))
    return config_from_dict(data)


def params_of(config: Config, space: list[Param]) -> dict[str, float]:
    return {
        p.key: getattr(getattr(config, p.key.split(".")[0]), p.key.split(".")[1]) for p in space
    }


def evaluate(
    config: Config,
    objective: str,
    settings: SweepSettings,
    execution: Execution | None = None,
    *,
    probe_impulse_ns: float = 15.0,
) -> dict[str, Any]:
    """The objective of one preset: ``{"objective": value, "rows": envelope rows or []}``."""
    settings = replace(settings, controllers=(PRESET_CONTROLLER,))
    if objective == "tracking":
        cells = probe_cells(config, settings, probe_impulse_ns)
        sweep = run(cells, settings, execution, "tracking")
        errors = []
        for o in sweep.outcomes:
            (r,) = o.rollouts.values()
            errors.append(r.max_dcm_error_m if r.survived else FALL_PENALTY_M)
        return {"objective": sum(errors) / len(errors), "rows": []}
    if objective not in OBJECTIVES:
        raise ValueError(f"objective {objective!r}: allowed {', '.join(OBJECTIVES)}")
    result = envelope(config, settings, execution)
    value = envelope_metric(result["rows"], objective, PRESET_CONTROLLER)
    return {"objective": value, "rows": result["rows"]}


def worst(objective: str) -> float:
    """The value reported for a suggestion that is not a valid preset."""
    return FALL_PENALTY_M if OBJECTIVES[objective][0] == "min" else 0.0


def _trial(
    params: dict[str, float],
    *,
    base: dict[str, Any],
    space: list[Param],
    objective: str,
    settings: SweepSettings,
    probe_impulse_ns: float,
) -> None:
    """A Ray Tune trainable: one objective evaluation, rollouts as Ray tasks."""
    from ray import tune

    try:
        config = apply_params(config_from_dict(base), params, space)
    except ConfigError as err:
        tune.report(
            {"objective": worst(objective), "rows": "[]", "error": str(err), "ended": time.time()}
        )
        return
    runner = RayRunner()  # the trial's Ray: tasks go to its placement group
    try:
        out = evaluate(
            config, objective, settings, Execution(runner=runner), probe_impulse_ns=probe_impulse_ns
        )
    finally:
        runner.close()
    tune.report(
        {
            "objective": out["objective"],
            "rows": json.dumps(out["rows"]),
            "error": "",
            "ended": time.time(),  # trials run one at a time: this orders them
        }
    )


@dataclass
class TuneSettings:
    objective: str = "weakest"
    trials: int = 20
    seed: int = 0
    probe_impulse_ns: float = 15.0  # tracking objective


def tune_preset(
    config: Config,
    tune_settings: TuneSettings,
    settings: SweepSettings,
    out: Path,
    *,
    progress: bool = False,
) -> dict[str, Any]:
    """Search the gains and timing of ``config``; returns the trials, the start and the best.

    Starts a local Ray instance (``settings.jobs`` CPUs) or joins ``settings.address`` unless
    Ray runs in this process already; Ray Tune's files go to ``out/ray_tune``.
    """
    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")  # Tune's old console output obeys verbose
    import optuna
    import ray
    from ray import tune
    from ray.tune.search import ConcurrencyLimiter
    from ray.tune.search.optuna import OptunaSearch

    objective = tune_settings.objective
    if objective not in OBJECTIVES:
        raise ValueError(f"--objective {objective!r}: allowed {', '.join(OBJECTIVES)}")
    mode, unit = OBJECTIVES[objective]
    settings = replace(settings, controllers=(PRESET_CONTROLLER,))
    space = search_space(config)
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    wall = time.perf_counter()
    own = ray_init(settings.jobs, settings.address)
    try:
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        runner = RayRunner()
        try:
            start = evaluate(
                config,
                objective,
                settings,
                Execution(runner=runner, progress=progress),
                probe_impulse_ns=tune_settings.probe_impulse_ns,
            )
        finally:
            runner.close()
        param_space = {
            p.key: (tune.loguniform if p.log else tune.uniform)(p.low, p.high) for p in space
        }
        search = ConcurrencyLimiter(
            OptunaSearch(metric="objective", mode=mode, seed=tune_settings.seed), max_concurrent=1
        )
        trainable = tune.with_parameters(
            _trial,
            base=config.to_dict(),
            space=space,
            objective=objective,
            settings=settings,
            probe_impulse_ns=tune_settings.probe_impulse_ns,
        )
        # the trial itself needs no CPU; one bundle per CPU for its rollout tasks
        trainable = tune.with_resources(
            trainable, tune.PlacementGroupFactory([{}] + [{"CPU": 1}] * cpus)
        )
        callbacks = [_ProgressCallback(tune_settings.trials)] if progress else []
        tuner = tune.Tuner(
            trainable,
            param_space=param_space,
            tune_config=tune.TuneConfig(
                search_alg=search, num_samples=tune_settings.trials, reuse_actors=True
            ),
            run_config=tune.RunConfig(
                storage_path=str((out / "ray_tune").resolve()),
                name=time.strftime("tune-%Y%m%d-%H%M%S"),
                verbose=0,
                callbacks=callbacks,
            ),
        )
        grid = tuner.fit()
        trials = []
        for r in grid:
            m = r.metrics or {}
            if "objective" not in m:
                continue  # a trial that errored (see out/ray_tune)
            trials.append(
                {
                    "trial_id": m.get("trial_id", ""),
                    "ended": float(m.get("ended", 0.0)),
                    "params": {p.key: p.round(float(r.config[p.key])) for p in space},
                    "objective": float(m["objective"]),
                    "rows": json.loads(m.get("rows", "[]")),
                    "error": m.get("error", ""),
                }
            )
        trials.sort(key=lambda t: t["ended"])
        if not trials:
            raise RuntimeError(f"no Tune trial finished; see {out / 'ray_tune'}")
        pick = max if mode == "max" else min
        best = pick(trials, key=lambda t: t["objective"])
        best_config = apply_params(config, best["params"], space)
        start_rows, best_rows = start["rows"], best["rows"]
        if objective == "tracking":  # envelopes for the report
            runner = RayRunner()
            try:
                env = replace(settings, controllers=(PRESET_CONTROLLER,))
                start_rows = envelope(config, env, Execution(runner=runner))["rows"]
                best_rows = envelope(best_config, env, Execution(runner=runner))["rows"]
            finally:
                runner.close()
    finally:
        if own:
            ray.shutdown()
    return {
        "preset": config.name,
        "robot": config.robot.model,
        "backend": settings.backend,
        "objective": objective,
        "mode": mode,
        "unit": unit,
        "seed": tune_settings.seed,
        "trials_requested": tune_settings.trials,
        "space": [asdict(p) for p in space],
        "settings": asdict(settings),
        "tune_settings": asdict(tune_settings),
        "start": {
            "params": params_of(config, space),
            "objective": start["objective"],
            "rows": start_rows,
        },
        "best": {**best, "rows": best_rows},
        "best_config": best_config.to_dict(),
        "trials": [{k: v for k, v in t.items() if k != "rows"} for t in trials],
        "wall_time_s": time.perf_counter() - wall,
    }


class _ProgressCallback:
    """A tqdm bar over Tune trials (made a ray.tune.Callback on first use)."""

    def __new__(cls, total: int):  # noqa: D102 - builds the Callback subclass lazily
        from ray.tune import Callback
        from tqdm import tqdm

        class Bar(Callback):
            def __init__(self) -> None:
                self.bar = tqdm(total=total, desc="trials", unit="trial", file=sys.stderr)
                self.best: float | None = None

            def on_trial_complete(self, iteration, trials, trial, **info) -> None:
                self.bar.update(1)

            def on_experiment_end(self, trials, **info) -> None:
                self.bar.close()

        return Bar()


def tuned_config(result: dict[str, Any]) -> Config:
    """The best preset of a tuning result, named and described as tuned."""
    cfg = config_from_dict(result["best_config"])
    best, start = result["best"], result["start"]
    text = (
        f"Tuned from {result['preset']!r} for the {result['objective']} objective "
        f"({result['backend']}, seed {result['seed']}, {len(result['trials'])} trials): "
        f"{start['objective']:.4g} → {best['objective']:.4g} {result['unit']}."
    )
    return cfg.replace(name=f"{result['preset']} (tuned: {result['objective']})", description=text)


def write_tuning(result: dict[str, Any], out: Path) -> list[Path]:
    """best.toml (loads back with load_preset), tune.json, and the report tune.png."""
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "best.toml", out / "tune.json", out / "tune.png"]
    save_preset(tuned_config(result), paths[0])
    paths[1].write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    plot_tuning(result, paths[2])
    return paths


def plot_tuning(result: dict[str, Any], path: Path) -> None:
    """Left: the objective of each trial, the best so far, the start.  Right: the envelope of
    the best preset against the starting one (polar, N·s)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    import numpy as np

    fig = plt.figure(figsize=(11.0, 4.8))
    ax = fig.add_subplot(1, 2, 1)
    values = np.array([t["objective"] for t in result["trials"]], dtype=float)
    n = np.arange(1, len(values) + 1)
    running = (np.maximum if result["mode"] == "max" else np.minimum).accumulate(values)
    ax.plot(n, values, "o", color="0.5", ms=5, label="trial")
    ax.step(n, running, where="post", color="C0", lw=2, label="best so far")
    ax.axhline(result["start"]["objective"], color="C3", ls="--", label="start")
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
    ax.set_xlabel("trial")
    ax.set_ylabel(f"{result['objective']} ({result['unit']})")
    goal = "higher" if result["mode"] == "max" else "lower"
    ax.set_title(f"{result['objective']} objective ({goal} is better)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    polar = fig.add_subplot(1, 2, 2, projection="polar")
    for name, style in (("start", "o--"), ("best", "s-")):
        rows = sorted(result[name]["rows"], key=lambda r: r["direction_deg"])
        if not rows:
            continue
        theta = np.radians([r["direction_deg"] for r in rows])
        radius = np.array([r["max_impulse_ns"] for r in rows])
        polar.plot(
            np.append(theta, theta[:1]),
            np.append(radius, radius[:1]),
            style,
            label=f"{name} ({result[name]['objective']:.3g} {result['unit']})",
        )
    polar.set_theta_zero_location("E")
    polar.set_title("max push impulse (N·s); 0° = forward, 90° = left", fontsize=9)
    polar.legend(loc="lower left", bbox_to_anchor=(-0.15, -0.15), fontsize=8)
    fig.suptitle(
        f"{result['preset']} ({result['robot']}, {result['backend']}): tuning, "
        f"seed {result['seed']}",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
