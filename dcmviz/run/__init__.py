"""The headless runner (``python -m dcmviz.run``, :mod:`.runner`), what it logs of a walk
(:mod:`.logs`) and the command-line helpers every dcmviz command shares (:mod:`.args`)."""

from dcmviz.run.logs import CSV_COLUMNS, CsvLog, TickLog, push_recovery
from dcmviz.run.runner import load_config, main, run_session, summary

__all__ = [
    "CSV_COLUMNS",
    "CsvLog",
    "TickLog",
    "load_config",
    "main",
    "push_recovery",
    "run_session",
    "summary",
]
