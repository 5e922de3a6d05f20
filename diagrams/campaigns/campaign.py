"""The campaign file: one scenario, fixed overrides and the axes it is swept along.

```yaml
name: joint_tour_speeds          # optional; default: the file's stem
scenario: ur10e_joint_tour       # a named scenario or a scenario file (relative to this file)
set: {settle_time: 0.2}          # overrides of every job (dotted keys reach nested fields)
grid:                            # the cross product of these lists
  max_speed: [0.5, 1.0, 1.5]     #   a list, or {linspace: [first, last, count]},
                                 #   or {range: [start, stop, step]} (stop excluded)
zip:                             # lists of one length, varied together (crossed with grid)
  a: [1, 2, 3]
  b: [4, 5, 6]
random:                          # `count` seeded draws (crossed with grid and zip)
  seed: 7
  count: 20
  draws:
    some.key: {uniform: [low, high]}     # low, high: numbers, or nested lists of one shape
    other.key: {integers: [low, high]}   # high excluded
    third.key: {choice: [a, b, c]}
repeat: {key: random_seed, count: 4, start: 0}  # key = start, start + 1, ... (crossed)
metrics: [coverage, press_error_mm.x]    # numeric metrics the task declares (dotted keys
                                         # of its summary); default: every scalar
```

Every job is the scenario with `set` and one value of each axis applied, as `--set` would.
Every number must be finite; counts are whole numbers >= 1, seeds and `repeat.start` whole
numbers >= 0, bounds ordered (low <= high); a campaign has at most MAX_JOBS (100000) jobs.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from guidedarm.systems.errors import ConfigurationError

CAMPAIGN_DIR = Path(__file__).resolve().parent
CAMPAIGN_KEYS = (
    "name",
    "description",
    "scenario",
    "set",
    "grid",
    "zip",
    "random",
    "repeat",
    "metrics",
)
DISTRIBUTIONS = ("uniform", "integers", "choice")
# The axis that numbers the random draws.
DRAW_AXIS = "draw"
# More jobs than this is a typo (a count off by orders of magnitude), not a campaign: its
# job list alone would fill the client's memory.
MAX_JOBS = 100_000


class CampaignError(ConfigurationError):
    """A campaign file is malformed; the message names the file and the key."""


@dataclass
class RandomDrawsConfig:
    """`count` draws of every key in `draws` from numpy's default_rng(seed), in file order.
    A draw is {uniform: [low, high]}, {integers: [low, high]} (high excluded) or
    {choice: [values]}."""

    seed: int = 0
    count: int = 0
    draws: dict[str, dict[str, Any]] = field(default_factory=dict)

    def Validate(self, source: str) -> None:
        if self.count < 1:
            raise CampaignError(f"{source}: random.count must be at least 1, got {self.count}")
        if self.seed < 0:
            raise CampaignError(f"{source}: random.seed must be at least 0, got {self.seed}")
        CheckFiniteNumbers(self.draws, "random.draws", source)
        if not isinstance(self.draws, dict) or not self.draws:
            raise CampaignError(f"{source}: random.draws must map scenario keys to draws")
        for key, spec in self.draws.items():
            if (
                not isinstance(spec, dict)
                or len(spec) != 1
                or next(iter(spec)) not in DISTRIBUTIONS
            ):
                raise CampaignError(
                    f"{source}: random.draws.{key} must be one of "
                    f"{{uniform: [low, high]}}, {{integers: [low, high]}}, {{choice: [values]}}"
                )
            (kind, args) = next(iter(spec.items()))
            if not isinstance(args, list) or (kind != "choice" and len(args) != 2) or not args:
                raise CampaignError(f"{source}: random.draws.{key}.{kind}: bad arguments {args!r}")
            if kind != "choice":
                try:
                    low, high = (np.asarray(a, float) for a in args)
                except (TypeError, ValueError):
                    raise CampaignError(
                        f"{source}: random.draws.{key}.{kind}: low and high must be numbers "
                        f"or lists of numbers of one shape, got {args!r}"
                    ) from None
                whole = np.all(low == np.round(low)) and np.all(high == np.round(high))
                if kind == "integers" and not whole:
                    raise CampaignError(
                        f"{source}: random.draws.{key}.integers: low and high must be whole "
                        f"numbers, got {args!r}"
                    )
                if low.shape != high.shape:
                    raise CampaignError(
                        f"{source}: random.draws.{key}.{kind}: low and high must have one "
                        f"shape, got {args!r}"
                    )
                empty = np.any(high < low) or (kind == "integers" and np.any(high <= low))
                if empty:
                    raise CampaignError(
                        f"{source}: random.draws.{key}.{kind}: need low <= high (integers: "
                        "low < high) of one shape"
                    )

    def Draw(self) -> list[dict[str, Any]]:
        """The `count` draws, each a mapping key -> value (plain Python values)."""
        rng = np.random.default_rng(self.seed)
        draws = []
        for _ in range(self.count):
            values = {}
            for key, spec in self.draws.items():
                (kind, args) = next(iter(spec.items()))
                if kind == "uniform":
                    value = rng.uniform(np.asarray(args[0], float), np.asarray(args[1], float))
                elif kind == "integers":
                    value = rng.integers(np.asarray(args[0]), np.asarray(args[1]))
                else:
                    value = args[int(rng.integers(len(args)))]
                values[key] = (
                    value.tolist() if isinstance(value, np.ndarray | np.generic) else value
                )
            draws.append(values)
        return draws


@dataclass
class RepeatConfig:
    """`count` jobs with `key` set to start, start + 1, ... (a seed of the scenario)."""

    key: str = ""
    count: int = 0
    start: int = 0

    def Validate(self, source: str) -> None:
        if not self.key or self.count < 1:
            raise CampaignError(
                f"{source}: repeat needs a scenario key (a seed) and a count >= 1, got "
                f"key '{self.key}', count {self.count}"
            )
        if self.start < 0:
            raise CampaignError(
                f"{source}: repeat.start (a seed) must be at least 0, got {self.start}"
            )


@dataclass
class CampaignConfig:
    """A campaign (see the module docstring). `scenario` is a scenario name or a resolved
    path; `source` is the campaign file it came from."""

    name: str
    scenario: str
    source: str = ""
    description: str = ""
    set: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list[Any]] = field(default_factory=dict)
    zip: dict[str, list[Any]] = field(default_factory=dict)
    random: RandomDrawsConfig | None = None
    repeat: RepeatConfig | None = None
    metrics: list[str] | None = None

    def Validate(self) -> None:
        source = self.source or self.name
        for block in ("grid", "zip"):
            for key, values in getattr(self, block).items():
                if not values:
                    raise CampaignError(f"{source}: {block} key '{key}' has no values")
        lengths = {len(v) for v in self.zip.values()}
        if len(lengths) > 1:
            raise CampaignError(
                f"{source}: the zip lists must have one length, got "
                + ", ".join(f"{k}: {len(v)}" for k, v in self.zip.items())
            )
        for block in ("set", "grid", "zip"):
            CheckFiniteNumbers(getattr(self, block), block, source)
        if self.random is not None:
            self.random.Validate(source)
        if self.repeat is not None:
            self.repeat.Validate(source)
        if self.JobCount() > MAX_JOBS:
            raise CampaignError(
                f"{source}: {self.JobCount()} jobs, more than the {MAX_JOBS} a campaign may have"
            )
        seen: dict[str, str] = {}
        for block, keys in self.KeysByBlock().items():
            for key in keys:
                if key == DRAW_AXIS:
                    raise CampaignError(
                        f"{source}: {block} key '{DRAW_AXIS}' is the column that numbers the "
                        "random draws, not a scenario key"
                    )
                if key.split(".")[:2] == ["station", "hardware"]:
                    raise CampaignError(
                        f"{source}: {block} key '{key}' has no effect in a campaign (its jobs "
                        "run in simulation, which reads no driver setting): remove it"
                    )
                if key in seen:
                    raise CampaignError(f"{source}: key '{key}' is in both {seen[key]} and {block}")
                seen[key] = block
        if self.metrics is not None and (
            not isinstance(self.metrics, list)
            or not self.metrics
            or not all(isinstance(m, str) and m for m in self.metrics)
        ):
            raise CampaignError(f"{source}: metrics must be a list of summary keys")
        twice = sorted({m for m in self.metrics or [] if self.metrics.count(m) > 1})
        if twice:
            raise CampaignError(f"{source}: metric '{twice[0]}' is listed twice")

    def JobCount(self) -> int:
        """grid x zip x random draws x repeat, without expanding them."""
        count = math.prod(len(v) for v in self.grid.values())
        count *= len(next(iter(self.zip.values()))) if self.zip else 1
        count *= self.random.count if self.random else 1
        return count * (self.repeat.count if self.repeat else 1)

    def KeysByBlock(self) -> dict[str, list[str]]:
        """The scenario keys each block of the campaign sets."""
        return {
            "set": list(self.set),
            "grid": list(self.grid),
            "zip": list(self.zip),
            "random": list(self.random.draws) if self.random else [],
            "repeat": [self.repeat.key] if self.repeat else [],
        }

    def AxisNames(self) -> list[str]:
        """The columns that tell the jobs apart, in expansion order."""
        random = [DRAW_AXIS, *self.random.draws] if self.random else []
        repeat = [self.repeat.key] if self.repeat else []
        return [*self.grid, *self.zip, *random, *repeat]

    def AxisPoints(self) -> list[dict[str, Any]]:
        """One mapping axis -> value per job: grid x zip x random draws x repeat."""
        grid = [
            dict(zip(self.grid, v, strict=True)) for v in itertools.product(*self.grid.values())
        ]
        count = len(next(iter(self.zip.values()))) if self.zip else 1
        zipped = [{k: v[i] for k, v in self.zip.items()} for i in range(count)]
        draws = (
            [{DRAW_AXIS: i, **d} for i, d in enumerate(self.random.Draw())] if self.random else [{}]
        )
        repeat = self.repeat
        repeats = [{repeat.key: repeat.start + i} for i in range(repeat.count)] if repeat else [{}]
        return [
            {**g, **z, **d, **r} for g, z, d, r in itertools.product(grid, zipped, draws, repeats)
        ]

    def Resolved(self) -> dict[str, Any]:
        """The campaign with every list spelled out: what DIR/campaign.yaml records."""
        resolved: dict[str, Any] = {"name": self.name, "scenario": self.scenario}
        if self.description:
            resolved["description"] = self.description
        for block in ("set", "grid", "zip"):
            if getattr(self, block):
                resolved[block] = getattr(self, block)
        if self.random:
            resolved["random"] = vars(self.random)
        if self.repeat:
            resolved["repeat"] = vars(self.repeat)
        if self.metrics is not None:
            resolved["metrics"] = self.metrics
        return resolved


def CheckFiniteNumbers(value: Any, key: str, source: str) -> None:
    """Refuses (CampaignError naming the key) a NaN or infinite number anywhere in `value`
    (nested lists and mappings)."""
    if isinstance(value, dict):
        for k, v in value.items():
            CheckFiniteNumbers(v, f"{key}.{k}", source)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            CheckFiniteNumbers(v, f"{key}[{i}]", source)
    elif isinstance(value, float) and not math.isfinite(value):
        raise CampaignError(f"{source}: {key} must be a finite number, got {value}")
