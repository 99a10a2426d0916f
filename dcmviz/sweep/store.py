"""Rollout results on disk as they finish: one JSON line each, so an interrupted sweep resumes
without redoing them (``--resume``).

A rollout is identified by its trial (the preset with the controller set, backend, push timing)
and the push force, so a resumed sweep finds its finished rollouts whatever order they ran in,
and rollouts shared by several cells or map points run once.  Lines::

    {"kind": "trial", "trial": KEY, "backend": ..., "start_s": ..., "config": {...}}
    {"kind": "rollout", "trial": KEY, "force": [fx, fy, fz], "survived": true, ...}

A line cut short by a kill is ignored when the file is read back.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

from dcmviz.sweep.search import RolloutResult, Trial

ROLLOUTS_FILE = "rollouts.jsonl"


def trial_record(trial: Trial) -> dict[str, Any]:
    """The trial as plain JSON data (the preset in the TOML layout)."""
    return {
        "config": trial.config.to_dict(),
        "backend": trial.backend,
        "start_s": trial.start_s,
        "duration_s": trial.duration_s,
        "end_s": trial.end_s,
        "body": trial.body,
        "ramp_s": trial.ramp_s,
    }


def trial_key(trial: Trial) -> str:
    """A short stable hash of everything that determines the trial's rollouts."""
    text = json.dumps(trial_record(trial), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _force_key(force: Sequence[float]) -> tuple[float, float, float]:
    return (float(force[0]), float(force[1]), float(force[2]))


class RolloutStore:
    """Finished rollouts by (trial key, force), kept in memory and appended to ``path``.

    ``path`` None keeps them in memory only.  Without ``resume`` an existing file is started
    afresh; with it, its rollouts are read back and reused.
    """

    def __init__(self, path: str | Path | None = None, *, resume: bool = False) -> None:
        self.path = None if path is None else Path(path)
        self._results: dict[tuple[str, tuple[float, float, float]], RolloutResult] = {}
        self._trials: set[str] = set()
        self.loaded = 0
        self._file: IO[str] | None = None
        if self.path is None:
            return
        if resume and self.path.exists():
            self._read()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("a" if resume else "w", encoding="utf-8")

    def _read(self) -> None:
        assert self.path is not None
        with self.path.open(encoding="utf-8") as f:
            for line in f:
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue  # a line cut short by a kill
                if not isinstance(rec, dict):
                    continue
                if rec.get("kind") == "trial":
                    self._trials.add(rec["trial"])
                elif rec.get("kind") == "rollout":
                    try:
                        key = (rec["trial"], _force_key(rec["force"]))
                        self._results[key] = RolloutResult.from_dict(rec)
                    except (KeyError, TypeError, ValueError, IndexError):
                        continue
        self.loaded = len(self._results)

    def __len__(self) -> int:
        return len(self._results)

    def get(self, key: str, force: Sequence[float]) -> RolloutResult | None:
        """The stored result of the rollout of trial ``key`` with ``force``, if any."""
        return self._results.get((key, _force_key(force)))

    def add(self, key: str, trial: Trial, force: Sequence[float], result: RolloutResult) -> None:
        """Keep a finished rollout and append it to the file at once (flushed)."""
        f = _force_key(force)
        self._results[(key, f)] = result
        if self._file is None:
            return
        if key not in self._trials:
            self._trials.add(key)
            self._write({"kind": "trial", "trial": key, **trial_record(trial)})
        self._write({"kind": "rollout", "trial": key, "force": list(f), **result.to_dict()})

    def _write(self, rec: dict[str, Any]) -> None:
        assert self._file is not None
        self._file.write(json.dumps(rec) + "\n")
        self._file.flush()

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> RolloutStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
