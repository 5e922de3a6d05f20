"""ContinuousConfig: the settings of continuous path following (ContinuousFollower; its
mathematics in continuous_follower_math and continuous_follower_estimate)."""

import math
from dataclasses import dataclass

from guidedarm.systems.config_checks import CheckFields, InRange, Positive
from guidedarm.systems.errors import ConfigurationError


@dataclass
class ContinuousConfig:
    """Continuous following (motion `continuous`; m, s, deg).

    speed: cruise speed of the tool along the hose (m/s; 0.11: with the confidence's
        share, 88-97 mm/s along the 24 test hoses, docs/path_following.md); min_speed: the
        floor of the adapted speed (m/s); acceleration: the tool's speed change (m/s^2).
    lateral_acceleration: in a bend of curvature k (the fit's, less two standard
        errors) the speed is at most sqrt(lateral_acceleration / k) and
        max_turn_rate_deg / k (m/s^2).
    look_ahead: how far the target may run past the latest hose estimate (m): it brakes
        so as to stop there, v <= sqrt(2 acceleration (look_ahead - lead)), and leads the
        latest estimate by the arm's lag and the reading's age (5-8 mm at 0.1 m/s), so
        0.015 held the target near 80 mm/s and 0.03 lets it cruise (a speed above
        sqrt(2 acceleration look_ahead) is refused: the target would never reach it).
    fit_length: length of hose behind the latest estimate fitted by the quadratic (m;
        0.045: 0.4 s of readings at the cruise, a heading and curvature less noisy than
        0.03's, whose maxima at 0.1 m/s were several mm larger); min_fit_points: readings
        needed before the fit's tangent and curvature are used (the scenario refuses a
        speed above fit_length / (min_fit_points x the ToF period), 0.28 m/s by default).
    spread_limit: the standard error of the estimated hose point at the tool (m) at which
        the confidence reaches 0; the speed falls from `speed` toward min_speed with the
        confidence (the fraction of readings in the fit window that saw the hose, times
        1 - (spread / spread_limit)^2); 0.1 mm to 50 mm (a hose's width).
    gate: a hose point farther than this from the fit's extrapolation (once the fit has
        min_fit_points) is an outlier, counted as a reading without the hose (m): past the
        hose's end the cones still see its end cap behind the detection plane, each
        reading a little farther off. 0.5 mm (below the estimates' own scatter, every
        reading would be an outlier) to 0.1 m. Four outliers in a row that move along with
        the tool and that a refit with most of the window's earlier readings holds within
        the gate are the hose instead (the fit had left it; continuous_follower_estimate).
    correction_gain: the target moves toward the estimated path at this rate times the
        distance, and its x axis turns toward the path's heading at this rate times the
        angle (1/s; a first-order filter of the fit's noise).
    max_correction_speed: the fastest correction of the target's position (m/s).
    max_turn_rate_deg: the fastest turn of the target's x axis (deg/s; 60: a bend of the
        random hoses' smallest radius, 0.1 m, turns the tool 63 deg/s at 0.11 m/s).
    heading_tolerance_deg: the target's x axis lagging the estimated heading by more than
        this slows the target in proportion (deg).
    lag_tolerance: the tool farther than this from the target at a reading (the arm cannot
        keep up, e.g. its wrist turning at its joint limits) slows the target in proportion
        (m; 0: off). 0.004: a little above the 1-4 mm the fed-forward servo keeps.
    servo_period: the target and the differential IK's tick (s); servo_gain: the
        differential IK's gain on the tool's pose error (1/s); servo_feedforward: the share
        of the target's own velocity the differential IK adds to that feedback (0 to 1;
        1 by default: without it the arm lags the target by the feedback's braking curve,
        v^2 / 2 a, 15 mm at 0.1 m/s, which eats the look-ahead); rotation_weight: the
        length (m) a rotation of 1 rad of the tool counts as against its position (the
        position, which the tracking needs, comes first; 1 mm to 1 m, the arm's reach);
        roll_weight: the share of that weight of the roll about x_T (the hose's axis): the
        detection does not need the roll, but the tool's clearance does (its side arm
        reaches 34 mm below the hose's centre and 69 mm out, so 10 deg of roll lowers its
        corner by 11 mm); 0.3 keeps it within 5 deg on paper_path_4, 0.1 let it wander to
        18 deg; servo_damping: the largest damping of the least
        squares, reached at a singularity (differential_ik_servo_math; a singular value
        of the weighted Jacobian, m/rad, from its floor MIN_DAMPING 1e-3 to 1).
    history: the measured joints kept for motion compensation (s).
    loss_distance: travel past the latest estimate without the hose before a search (m).
    search_distance: how far past the latest estimate a search goes (m).
    search_speed: the tool's speed while it searches and backs up (m/s).
    search_turns_deg: after the straight search, retries from the latest estimate in these
        directions, turned about the world z axis (deg); every one lost = the hose's end.
        Empty (the default): the straight search alone; a retry turns the tool about its
        centre, which swings the wrist fast (20 deg: 55 mm) and the arm fell behind.
    min_range: a valid range below this (m) means the tool is at the hose (a bend tighter
        than the tool can turn through, e.g. a kink): the run fails at that reading, in any
        mode, and the arm stops instead of pressing on (a 90 degree kink of zero radius:
        0.36 s of contact instead of 6.4 s). Following keeps the hose 28-50 mm from every
        sensor (4 mm noise included); 0 turns the check off.
    thickening_min, thickening_hold: a section thicker than the hose (a bracket's collar,
        a clamp; hose_thickness): the hose's radius is measured whenever five or six
        sensors see it, and when the median excess over the known radius of two or more
        measurements within the last thickening_hold of travel (m) passes thickening_min
        (m), the hose centre is estimated with that larger radius; thickening_min 0 turns
        the test off (and the slowing below with it).
    thickening_max: a larger excess (m) is not a section of hose (a bracket's post in a
        flank cone) and counts as no measurement; above thickening_min.
    fixture_speed: the fastest the target runs (m/s) from the first reading on a thicker
        section until it is half of fit_length past its last one, while the hose fit still
        holds the readings its facing sensors took of the section's ends (hose_thickness);
        at least min_speed, at or above `speed` no slowing. 0.09: with the gate's recovery
        of a fit bent off the hose (continuous_follower_estimate) 127 of 128 test runs meet
        the goals, paper_path_4 with three brackets at 83 mm/s; 0.08 left one run over a
        goal, the cruise three (docs/path_following.md, What is not hose).
    """

    speed: float = Positive(0.11)
    min_speed: float = Positive(0.02)
    acceleration: float = Positive(0.4)
    lateral_acceleration: float = Positive(0.1)
    look_ahead: float = Positive(0.03)
    fit_length: float = Positive(0.045)
    min_fit_points: int = InRange(3, 10000, 8)
    spread_limit: float = InRange(1e-4, 0.05, 0.006)
    gate: float = InRange(5e-4, 0.1, 0.008)
    correction_gain: float = Positive(8.0)
    max_correction_speed: float = Positive(0.03)
    max_turn_rate_deg: float = Positive(60.0)
    heading_tolerance_deg: float = InRange(0.5, 90.0, 10.0)
    lag_tolerance: float = InRange(0.0, 0.05, 0.004)
    servo_period: float = Positive(0.008)
    servo_gain: float = Positive(20.0)
    servo_feedforward: float = InRange(0.0, 1.0, 1.0)
    rotation_weight: float = InRange(1e-3, 1.0, 0.05)
    roll_weight: float = InRange(0.0, 1.0, 0.3)
    servo_damping: float = InRange(1e-3, 1.0, 0.01)
    history: float = Positive(0.3)
    loss_distance: float = Positive(0.008)
    search_distance: float = Positive(0.025)
    search_speed: float = Positive(0.02)
    search_turns_deg: list[float] = InRange(-90.0, 90.0, factory=list)
    min_range: float = InRange(0.0, 0.05, 0.015)
    thickening_min: float = InRange(0.0, 0.01, 0.0015)
    thickening_hold: float = Positive(0.005)
    thickening_max: float = InRange(1e-4, 0.05, 0.005)
    fixture_speed: float = Positive(0.09)

    def ServoWeights(self) -> list[float]:
        """The DifferentialIkServo's six weights (roll, pitch, yaw about T; x, y, z)."""
        w = self.rotation_weight
        return [self.roll_weight * w, w, w, 1.0, 1.0, 1.0]

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field or rule."""
        CheckFields(self)
        if not self.min_speed <= self.speed:
            raise ConfigurationError("continuous: need min_speed <= speed")
        if not self.min_speed <= self.fixture_speed:
            raise ConfigurationError("continuous: need min_speed <= fixture_speed")
        if not self.thickening_min < self.thickening_max:
            raise ConfigurationError("continuous: need thickening_min < thickening_max")
        if not self.search_speed <= self.speed:
            raise ConfigurationError("continuous: need search_speed <= speed")
        if not self.loss_distance < self.search_distance:
            raise ConfigurationError("continuous: need loss_distance < search_distance")
        if not self.loss_distance < self.look_ahead:
            raise ConfigurationError("continuous: need loss_distance < look_ahead")
        if not self.history >= 10 * self.servo_period:
            raise ConfigurationError("continuous: need history >= 10 servo_period")
        if not self.speed <= math.sqrt(2 * self.acceleration * self.look_ahead):
            # Advance brakes the target to stop within the look-ahead, so it never runs
            # faster than this.
            raise ConfigurationError(
                "continuous: need speed <= sqrt(2 acceleration look_ahead), the fastest the "
                "target can run and still stop within the look-ahead"
            )
