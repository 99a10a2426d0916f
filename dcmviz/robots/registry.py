"""The robots by name or file: :func:`get_spec` builds a robot file's model once per process and
returns its planning facts (:class:`~dcmviz.robots.spec.RobotSpec`).

Separate from :mod:`.spec` (the facts) and :mod:`.model` (Pinocchio, imported on first use) so
that neither imports the other's caller.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

from dcmviz.robots.file import BUILTIN_ROBOTS, RobotFileError
from dcmviz.robots.spec import RobotSpec


class _BuiltinSpecs(Mapping[str, RobotSpec]):
    """The built-in robots' specs by name, each built from its robot file when first read."""

    def __getitem__(self, name: str) -> RobotSpec:
        if name not in BUILTIN_ROBOTS:
            raise KeyError(name)
        return get_spec(name)

    def __iter__(self) -> Iterator[str]:
        return iter(BUILTIN_ROBOTS)

    def __len__(self) -> int:
        return len(BUILTIN_ROBOTS)


SPECS: Mapping[str, RobotSpec] = _BuiltinSpecs()
ROBOT_NAMES = BUILTIN_ROBOTS


def get_spec(model: str) -> RobotSpec:
    """The spec of ``robot.model``: a built-in robot's name or the path of a robot file
    (``docs/robots.md``), built and checked once per process and file version.  ValueError
    (:class:`~dcmviz.robots.file.RobotFileError`) naming ``robot.model``, the file's key and what
    was expected otherwise."""
    from dcmviz.robots.model import build_model  # Pinocchio: imported when first needed

    try:
        return build_model(model).spec
    except RobotFileError as err:
        raise RobotFileError(f"robot.model = {model!r}: {err}") from None
