"""Command-line helpers shared by the headless runner (``dcmviz.run``) and the sweeps
(``dcmviz.sweep``): an argparse parser whose errors are one line, and argument types that name
the bad value and what is allowed.
"""

from __future__ import annotations

import argparse
import math


class BadInput(Exception):
    """Bad command-line input; the message is the one line printed on stderr."""


class Parser(argparse.ArgumentParser):
    """argparse that reports errors as one line and raises instead of exiting."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise BadInput(message)


def positive_seconds(text: str) -> float:
    """argparse type: a finite number of seconds > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number (seconds, > 0)") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"{text!r}: must be a finite number of seconds > 0")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer ≥ 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: must be ≥ 1")
    return value


def fraction(text: str) -> float:
    """argparse type: a number in [0, 1)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number in [0, 1)") from None
    if not 0.0 <= value < 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be in [0, 1)")
    return value
