"""Telling the hose from what is fitted on it (a bracket's collar, a clamp's band): the
hose's radius measured along the way (continuous following).

Units: m.

A section of hose thicker by e brings its surface e nearer to every sensor facing it, which
the ranging estimator, fitting a hose of the known radius r, reads as the hose moved e
toward both sensor arms (4.2 mm for a collar 3 mm thicker): the sensors facing the hose
cannot tell the two apart. The flank sensors can: they see the hose with their cones' edge
rays, where a larger radius and a shift change the ranges differently, and a collar, wider
than the hose, comes into all four flank cones at once. Whenever five or six sensors see the
hose, DetectionGrid.RadiusEstimate fits its radius with its centre (with the sensors' noise
the excess over r reads 0.3 mm at the median on plain hose, -0.5 to 1.7 mm for 80 % of
the readings; 3.4 mm on a 3 mm collar, 2.1 to 4.8 mm).

Thickness keeps the radius excesses measured over the last `thickening_hold` (5 mm) of the
tool's travel, a reading that fewer than five sensors see counting as 0 (a thicker section
would reach the flank cones too); once MIN_SAMPLES of them have a median above
`thickening_min` (1.5 mm) the readings are on a thicker section, and the follower estimates
the hose centre with the radius r + that median (rounded to QUANTUM), which puts the
collar's centre, the hose's, where it is. A reading the hose fit would reject as an
outlier with that radius and take with the hose's own keeps the hose's (the section ended,
or the fit followed its first readings before the radius was measured). An excess above
`thickening_max` (5 mm) is no section of hose: a bracket's post in a flank cone lets the
radius fit grow the hose until it reaches the post (5.7-9 mm by random_34's end bracket).

The section can also slow the target (SpeedCap): the facing cones, 25 deg wide, see a
collar up to 9 mm before and after the detection plane reaches it, where no radius tells
it from the hose, and those readings stay in the hose fit for `fit_length` of travel; at
the cruise the target extrapolates the bent fit up to `look_ahead` past them. From the
first reading on a thicker section until the target is half of fit_length past its last
one the target runs at most `fixture_speed` (90 mm/s). Where the bent fit rejected the
hose itself, the estimate's recovery of a run of outliers (continuous_follower_estimate)
takes the hose back; the slowing keeps the maxima past a collar lower
(docs/path_following.md, What is not hose).
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass

from guidedarm.systems.path_following.continuous_follower_config import ContinuousConfig

# The excess applied is a multiple of this (m): the follower keeps one detection grid per
# radius it meets.
QUANTUM = 2.5e-4
# The measurements a thicker section needs within thickening_hold (one may be a misfit).
MIN_SAMPLES = 2


@dataclass(frozen=True)
class Thickness:
    """The radius excesses measured (path coordinate s, excess; m) over the last
    thickening_hold of travel, and the excess the estimator applies (m, >= 0)."""

    samples: tuple[tuple[float, float], ...] = ()
    excess: float = 0.0
    found_at: float = -float("inf")

    def With(self, s: float, measured: float | None, config: ContinuousConfig) -> Thickness:
        """The thickness after a reading at path coordinate s whose radius excess (m) was
        measured, or None when too few sensors saw the hose to measure it."""
        samples = tuple((a, e) for a, e in self.samples if abs(s - a) <= config.thickening_hold)
        if measured is not None and measured <= config.thickening_max:
            samples += ((s, measured),)
        if config.thickening_min <= 0 or len(samples) < MIN_SAMPLES:
            return Thickness(samples, 0.0, self.found_at)
        median = statistics.median(e for _, e in samples)
        excess = QUANTUM * round(median / QUANTUM) if median > config.thickening_min else 0.0
        return Thickness(samples, excess, s if excess else self.found_at)

    def SpeedCap(self, s: float, config: ContinuousConfig) -> float:
        """The fastest the target may run at its path coordinate s (m/s): fixture_speed up
        to half of fit_length past the last reading on a thicker section (module
        docstring), the cruise `speed` elsewhere."""
        if s - self.found_at <= config.fit_length / 2:
            return config.fixture_speed
        return config.speed
