"""The ranges the ToF tool's sensors read for a hose, and the fit of the hose centre to
measured ranges: the model behind the ranging estimator (detection_grid, Wawrzyniak et al.'s
tool).

A sensor's cone sees a hose centred at c in the detection plane (the tool frame T) at the
nearest in-plane ray of the cone; a hose crossing the plane obliquely is a cylinder of
that axis through c. The Gauss-Newton fit moves c to match the ranges of the trusted
sensors.

The model and both fits run in a compiled kernel (csrc/hose_range.c, built by the install):
in Python a reading's fits evaluated the model several hundred times (the radius fit alone
some 250 oblique ranges of 19 rim rays each) and cost about 0.6 ms, a third of the
continuous loop's interpreter time. tests/hose_range_model_reference.py keeps the Python
implementation the kernel is tested against (the same values on random inputs; the radius
fit's 3-column least squares by a Jacobi SVD there, LAPACK's in the reference, to 1e-12).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from guidedarm.systems.small_vectors import Vector
from guidedarm.systems.tof import _hose_range

# The ranges RadiusFit needs: three unknowns, and at least two of them flank ranges; the
# radii it starts from, as multiples of the known one.
RADIUS_FIT_SENSORS = 5
RADIUS_STARTS = (1.0, 1.3)
# The radius fit's range for a cone that misses the modelled hose by a gap of at most
# MAX_MISS (m): the range along the rim ray of the hose's closest approach plus MISS_SLOPE
# times the gap (RadiusFit).
MISS_SLOPE = 1.0
MAX_MISS = 0.004
# Rim rays over the half of a cone's rim that faces an oblique hose (CylinderRange).
BOUNDARY_SAMPLES = 19
_RIM_PHI = np.linspace(-math.pi / 2, math.pi / 2, BOUNDARY_SAMPLES)


@dataclass(frozen=True)
class HoseRangeModel:
    """The range model of a tool's sensors for a hose of radius hose_radius (m).

    emitters, axes: each sensor's origin and unit line of sight (+z) in T (floats).
    cone_angle: the sensors' full cone angle (rad).
    """

    emitters: Sequence[Vector]
    axes: Sequence[Vector]
    hose_radius: float
    cone_angle: float

    def __post_init__(self) -> None:
        half = self.cone_angle / 2
        rim = [
            (math.sin(half) * math.cos(phi), math.sin(half) * math.sin(phi))
            for phi in _RIM_PHI.tolist()
        ]
        # The kernel's model buffer (csrc/hose_range.c).
        packed = [
            *(x for e in self.emitters for x in e),
            *(x for z in self.axes for x in z),
            self.hose_radius,
            math.cos(half),
            math.sin(half),
            *(x for pair in rim for x in pair),
        ]
        object.__setattr__(self, "_packed", np.array(packed, float).tobytes())

    def PlaneRange(self, k: int, c: Vector, radius: float | None = None) -> float | None:
        """Range (m) sensor k reads for a hose perpendicular to the detection plane centred
        at c (T), or None when its cone misses the hose: the nearest in-plane ray of the
        cone. radius: the hose's (m), hose_radius when None."""
        r = self.hose_radius if radius is None else radius
        return _hose_range.PlaneRange(self._packed, k, c, r)

    def CylinderRange(
        self, k: int, c: Vector, axis: Vector, radius: float | None = None
    ) -> float | None:
        """Range (m) sensor k reads for the cylinder of radius `radius` (hose_radius when
        None), unit axis `axis` through c (T), or None when its cone misses it.

        A hose crossing the detection plane obliquely is nearer to some cones and farther
        from others than the perpendicular one PlaneRange assumes (its section in the
        plane is an ellipse of semi-axis r / cos(tilt)): 3 mm of estimate at 20 deg. The
        nearest point of the cylinder is at distance - r toward the foot of the emitter's
        perpendicular on the axis; when that direction leaves the cone the nearest return
        is on the cone's rim, minimised over BOUNDARY_SAMPLES rim rays on the side facing
        the axis and a parabola through the least three (smooth in c, which the
        Gauss-Newton's finite differences need)."""
        r = self.hose_radius if radius is None else radius
        return _hose_range.CylinderRange(self._packed, k, c, axis, r)

    def RangeFunction(
        self, axis: np.ndarray | None
    ) -> Callable[[int, Vector, float | None], float | None]:
        """(k, c, radius=None) -> the range sensor k reads for a hose centred at c (T): along
        `axis` (unit, T; CylinderRange), or perpendicular to the detection plane when axis
        is None (PlaneRange)."""
        if axis is None:
            return self.PlaneRange
        axis_floats = tuple(axis.tolist())
        return lambda k, c, radius=None: self.CylinderRange(k, c, axis_floats, radius)

    def Refine(
        self,
        c: Vector,
        ranges: list[float],
        sensors: list[int],
        axis: np.ndarray | None,
        max_shift: float,
    ) -> Vector:
        """Gauss-Newton fit of the hose centre to the sensors' ranges, from c (a hose along
        `axis` when given); c itself when the fit has fewer than three ranges (two with
        `axis`) to use or moves more than max_shift (m, half the grid spacing: it left the
        grid cell it started in). Two ranges determine the centre exactly; the
        perpendicular model asks for a third to average, while an oblique hose moves even
        the two sensors trilateration uses. The centre moves in the plane of sensors 1 and
        4's lines of sight; the Jacobian is by finite differences, the 2 x 2 normal
        equations solved directly (the minimum-norm least squares when they are
        ill-conditioned), at most 8 steps."""
        return _hose_range.Refine(self._packed, c, ranges, sensors, _Floats(axis), max_shift)


def RadiusFit(
    model: HoseRangeModel,
    c: Vector,
    ranges: list[float],
    sensors: list[int],
    axis: np.ndarray | None,
    max_shift: float,
) -> tuple[Vector, float] | None:
    """Gauss-Newton fit of the hose's centre and radius together to the ranges of
    `sensors` (at least RADIUS_FIT_SENSORS of them with a modelled range), from each radius
    of RADIUS_STARTS times hose_radius (the flank cones miss a hose of the known radius that
    a thicker one reaches), its centre c moved e along sensors 1 and 4's lines of sight for
    a start e thicker than hose_radius (a thicker hose reads as one nearer those two);
    (centre, radius) of the start that fits best (RMS misfit), in T and m, or None when
    none keeps enough ranges, its centre within max_shift of c and its radius within
    [r / 2, 2 r]. At most 10 steps from each start, each the minimum-norm least squares of
    the 3-column finite-difference Jacobian.

    A sensor that read a range where the modelled hose misses its cone by at most MAX_MISS
    keeps its row: its model range runs on past the cone's rim (MISS_SLOPE times the gap
    added to the range along the rim ray of the hose's closest approach, continuous with the
    range where the rim ray grazes the hose), which moves the hose back into the cone, and
    the gap left at the end counts in the misfit. Dropping those rows left 63 % of the
    readings of plain hose with five or six sensors without a radius (6 % keeping them; eight
    test hoses with three brackets). A bracket's post in a flank cone can be reached by
    growing the radius: hose_thickness rejects such excesses (thickening_max).

    The sensors facing the hose read a thicker hose exactly as a hose moved toward them; the
    flank sensors, which see it with their cones' edge rays, read the radius differently
    from a shift, and with five or six ranges the three unknowns part."""
    return _hose_range.RadiusFit(
        model._packed,
        c,
        ranges,
        sensors,
        _Floats(axis),
        max_shift,
        RADIUS_FIT_SENSORS,
        RADIUS_STARTS,
        MISS_SLOPE,
        MAX_MISS,
    )


def _Floats(axis: np.ndarray | None) -> list[float] | None:
    return None if axis is None else axis.tolist()
