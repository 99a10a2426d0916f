"""Each foot's leg, hip to ankle, in a URDF or an MJCF model alike (:func:`find_legs`)."""

from __future__ import annotations

from collections.abc import Callable, Iterable

from dcmviz.robots.feet import SIDES
from dcmviz.robots.file import RobotFile
from dcmviz.robots.file import file_error as _err


def suggest(names: list[str], words: tuple[str, ...]) -> str:
    """Up to 8 of ``names`` containing one of ``words`` (else the first 8), for an error."""
    hits = [n for n in names if any(w in n.lower() for w in words)]
    return ", ".join(hits[:8]) if hits else ", ".join(names[:8])


def find_legs(
    rf: RobotFile,
    names: list[str],
    noun: str,
    source: str,
    chain_of: Callable[[str], Iterable[tuple[str, str]]],
    joint_word: str,
    root: str,
) -> dict[str, tuple[str, ...]]:
    """The leg joints of each foot, hip to ankle, for a URDF or an MJCF model alike.

    ``names`` are the model's links (bodies), ``chain_of(foot)`` yields the movable joints
    (name, kind) from a foot's link up to the root.  A foot or pushable body the model lacks, a
    leg joint that is not revolute, a leg of fewer than 3 joints or two legs sharing joints is
    refused naming its key (``noun``: "link" or "body"; ``joint_word``: the model's word for a
    revolute joint; ``root``: how to name the root in messages).
    """
    legs = {}
    for side in SIDES:
        foot = getattr(rf.feet, side)
        if foot.link not in names:
            raise _err(
                rf,
                f"feet.{side}.link = {foot.link!r}: no such {noun} in {source}; expected a "
                f"{noun} of the foot, e.g. {suggest(names, ('foot', 'ankle', 'sole', 'toe'))}",
            )
        chain = []
        for joint, kind in chain_of(foot.link):
            if kind != "revolute":
                raise _err(
                    rf,
                    f"feet.{side}.link = {foot.link!r}: leg joint {joint!r} is {kind}; expected "
                    f"{joint_word} leg joints",
                )
            chain.append(joint)
        if len(chain) < 3:
            raise _err(
                rf,
                f"feet.{side}.link = {foot.link!r}: no leg found: the chain from the root {root} "
                f"to it has {len(chain)} {joint_word} joint(s); expected a leg of at least 3 "
                "(hip, knee, ankle)",
            )
        legs[side] = tuple(reversed(chain))
    shared = set(legs["left"]) & set(legs["right"])
    if shared:
        raise _err(
            rf,
            f"feet.right.link = {rf.feet.right.link!r}: shares joints {sorted(shared)} with "
            f"feet.left.link = {rf.feet.left.link!r}; expected two separate legs",
        )
    for name, link in rf.bodies.items():
        if link not in names:
            raise _err(
                rf,
                f"bodies.{name} = {link!r}: no such {noun} in {source}; expected one of its "
                f"{noun}s, e.g. {suggest(names, ('torso', 'pelvis', 'base'))}",
            )
    return legs
