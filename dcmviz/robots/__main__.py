"""``python -m dcmviz.robots NAME|PATH ...``: load robot files and print what they derive."""

from __future__ import annotations

import sys

from dcmviz.robots.file import BUILTIN_ROBOTS, RobotFileError
from dcmviz.robots.lean import describe
from dcmviz.robots.report import report
from dcmviz.robots.robot import load_robot


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args or args[0] in ("-h", "--help"):
        print(
            f"usage: python -m dcmviz.robots NAME|PATH ...  (built-in: {', '.join(BUILTIN_ROBOTS)})"
        )
        return 0 if args else 2
    for model in args:
        try:
            robot = load_robot(model)
            print(report(robot.model))
            print(describe(robot))
        except RobotFileError as err:
            print(err, file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
