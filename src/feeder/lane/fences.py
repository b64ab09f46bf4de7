"""Fence configurations: what stands at Location 1 (downstream) and Location 2 (upstream).

A location holds ``none``, a ``straight`` fence at angle θ (between fence and direction of travel,
0 < θ < 90) or a ``curved`` fence at angle θ (0 ≤ θ ≤ 90). On the command line a location is written
``none``, ``straight:30`` or ``curved:45``; in file names a configuration is ``<loc1>_<loc2>`` with
each location as ``none``, ``straight30`` or ``curved45`` (e.g. ``straight30_none``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from feeder.errors import FeederError

TYPES = ("none", "straight", "curved")
# Open/closed angle ranges per type (degrees): straight excludes both ends, curved includes both.
ANGLE_RANGE = {"straight": (0.0, 90.0, False), "curved": (0.0, 90.0, True)}

_ID_RE = re.compile(r"^(none|straight|curved)(\d+(?:\.\d+)?)?$")


@dataclass(frozen=True, order=True)
class Fence:
    """One fence location: its type and angle in degrees (0 for ``none``)."""

    type: str
    angle: float = 0.0

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise FeederError(f"fence type {self.type!r} is not one of {', '.join(TYPES)}")
        if self.type == "none":
            if self.angle != 0.0:
                raise FeederError("a 'none' fence location takes no angle")
            return
        lo, hi, closed = ANGLE_RANGE[self.type]
        ok = lo <= self.angle <= hi if closed else lo < self.angle < hi
        if not ok:
            brackets = "[{}, {}]" if closed else "({}, {})"
            raise FeederError(f"{self.type} fence angle {self.angle:g} is outside {brackets.format(lo, hi)} degrees")

    @property
    def present(self) -> bool:
        return self.type != "none"

    @property
    def token(self) -> str:
        """File-name token: ``none``, ``straight30``, ``curved22.5``."""
        return "none" if self.type == "none" else f"{self.type}{self.angle:g}"

    @property
    def spec(self) -> str:
        """Command-line form: ``none``, ``straight:30``."""
        return "none" if self.type == "none" else f"{self.type}:{self.angle:g}"


def parse_location(text: str) -> Fence:
    """Parse ``none`` / ``straight:30`` / ``curved:45`` (command-line form)."""
    text = str(text).strip().lower()
    if text == "none":
        return Fence("none")
    kind, sep, angle = text.partition(":")
    if not sep:
        raise FeederError(f"fence {text!r}: expected none, straight:ANGLE or curved:ANGLE")
    try:
        value = float(angle)
    except ValueError:
        raise FeederError(f"fence {text!r}: angle {angle!r} is not a number") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise FeederError(f"fence {text!r}: angle must be finite")
    return Fence(kind, value)


def parse_token(token: str) -> Fence:
    """Parse a file-name token (``straight30``)."""
    m = _ID_RE.match(token)
    if not m:
        raise FeederError(f"fence token {token!r} is not none, straight<ANGLE> or curved<ANGLE>")
    kind, angle = m.group(1), m.group(2)
    if kind == "none":
        if angle:
            raise FeederError(f"fence token {token!r}: 'none' takes no angle")
        return Fence("none")
    if angle is None:
        raise FeederError(f"fence token {token!r} lacks an angle")
    return Fence(kind, float(angle))


def config_id(loc1: Fence, loc2: Fence) -> str:
    """File-name id of a fence configuration: ``<loc1>_<loc2>``."""
    return f"{loc1.token}_{loc2.token}"


def parse_config_id(text: str) -> tuple[Fence, Fence]:
    parts = text.split("_")
    if len(parts) != 2:
        raise FeederError(f"fence configuration {text!r} is not <loc1>_<loc2>")
    return parse_token(parts[0]), parse_token(parts[1])
