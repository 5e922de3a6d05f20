"""Declared bounds of config fields: the Bound of a number, the dataclass field helpers
that carry one (Positive, NonNegative, InRange, Bounded), and FieldError, the one-line
error naming a config's dotted key. systems/config_checks.py walks a config tree and
enforces them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import MISSING, dataclass
from typing import Any

from guidedarm.systems.errors import ConfigurationError

BOUND_KEY = "guidedarm.bound"  # a field's metadata key of its Bound


class FieldError(ConfigurationError):
    """A config value is out of its bounds; `key` is its dotted path in the config tree."""

    def __init__(self, key: str, why: str) -> None:
        self.key = key
        self.why = why
        super().__init__(f"key '{key}': {why}" if key else why)


@dataclass(frozen=True)
class Bound:
    """An interval for a number (both ends included unless open), and whether +-inf is
    admissible."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    allow_inf: bool = False

    def Violation(self, value: float) -> str | None:
        """Why `value` is out of bounds, or None; NaN is always out."""
        if not (self.allow_inf or math.isfinite(value)):
            return f"must be a finite number, got {value}"
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        if not (above and below):
            return f"must be {self}, got {value}"
        return None

    def __str__(self) -> str:
        if self.high == math.inf:
            return f"{'>' if self.low_open else '>='} {self.low:g}"
        if self.low == -math.inf:
            return f"{'<' if self.high_open else '<='} {self.high:g}"
        left, right = "(" if self.low_open else "[", ")" if self.high_open else "]"
        return f"in {left}{self.low:g}, {self.high:g}{right}"


FINITE = Bound()
POSITIVE = Bound(low=0.0, low_open=True)
NON_NEGATIVE = Bound(low=0.0)
UNIT_INTERVAL = Bound(low=0.0, high=1.0)
# A joint position (rad) beyond two turns either way is no joint of our arms (UR10e joints
# span +-2 pi); it bounds every joint vector of a scenario.
MAX_JOINT_POSITION = 4 * math.pi


def Positive(default: Any = MISSING, *, factory: Any = MISSING, allow_inf: bool = False) -> Any:
    """A dataclass field whose value (or each element) must be > 0."""
    return Bounded(Bound(low=0.0, low_open=True, allow_inf=allow_inf), default, factory)


def NonNegative(default: Any = MISSING, *, factory: Any = MISSING) -> Any:
    """A dataclass field whose value (or each element) must be >= 0."""
    return Bounded(NON_NEGATIVE, default, factory)


def InRange(
    low: float,
    high: float,
    default: Any = MISSING,
    *,
    factory: Any = MISSING,
    low_open: bool = False,
    high_open: bool = False,
) -> Any:
    """A dataclass field whose value (or each element) must lie between low and high."""
    return Bounded(Bound(low, high, low_open, high_open), default, factory)


def Bounded(bound: Bound, default: Any = MISSING, factory: Any = MISSING) -> Any:
    """A dataclass field carrying `bound` (enforced by config_checks.CheckFields)."""
    return dataclasses.field(default=default, default_factory=factory, metadata={BOUND_KEY: bound})
