"""The cell's virtual walls: the box the robot and the followed hose must stay inside.

Wawrzyniak et al. ("Three-Dimensional Path-Following with Articulated 6DoF Robot and ToF
Sensors", section 3.1) set the Nachi controller's safety walls to x, y in -550 .. +550 mm and
z from +5 mm, and gave the IK the same bounds; their path 4 moved the x+ wall to 850 mm.
The box is expressed in the arm's base frame B, so it travels with the arm.
"""

import math
from dataclasses import dataclass

import numpy as np

from guidedarm.systems.config_checks import Bound, Bounded, CheckFields
from guidedarm.systems.errors import ConfigurationError

# A wall may be left open (+-inf: the paper's z has no upper wall); NaN is refused.
_WALL = Bound(allow_inf=True)


@dataclass
class WorkspaceConfig:
    """Axis-aligned walls (m, the arm's base frame B); the default is the paper's cell.

    x: [lower, upper] walls along x (m, base frame).
    y: [lower, upper] walls along y (m, base frame).
    z: [lower, upper] along z (m, base frame); upper .inf: no ceiling.
    """

    x: list[float] = Bounded(_WALL, factory=lambda: [-0.55, 0.55])
    y: list[float] = Bounded(_WALL, factory=lambda: [-0.55, 0.55])
    z: list[float] = Bounded(_WALL, factory=lambda: [0.005, math.inf])

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first malformed axis."""
        CheckFields(self)
        for axis, bounds in (("x", self.x), ("y", self.y), ("z", self.z)):
            if len(bounds) != 2 or not bounds[0] < bounds[1]:
                raise ConfigurationError(f"{axis} must be [lower, upper] with lower < upper")

    def Lower(self) -> np.ndarray:
        """[x, y, z] lower bounds (m)."""
        return np.array([self.x[0], self.y[0], self.z[0]], float)

    def Upper(self) -> np.ndarray:
        """[x, y, z] upper bounds (m)."""
        return np.array([self.x[1], self.y[1], self.z[1]], float)

    def FirstOutside(self, p_B: np.ndarray) -> int | None:
        """Index of the first of the points (N, 3; m, frame B) outside the box, or None."""
        points = np.atleast_2d(p_B)
        outside = np.any((points < self.Lower()) | (points > self.Upper()), axis=1)
        return int(np.argmax(outside)) if outside.any() else None

    def Margin(self, p_B: np.ndarray) -> float:
        """The smallest distance (m) from the points (N, 3; m, frame B), all inside the box,
        to a wall."""
        points = np.atleast_2d(p_B)
        return float(min((points - self.Lower()).min(), (self.Upper() - points).min()))

    def Describe(self) -> str:
        """The box as `x [lo, hi], y [lo, hi], z [lo, hi]` (m)."""
        return ", ".join(
            f"{axis} [{bounds[0]:g}, {bounds[1]:g}]"
            for axis, bounds in (("x", self.x), ("y", self.y), ("z", self.z))
        )
