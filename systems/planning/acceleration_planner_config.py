"""PlannerConfig: the gains and settings of the acceleration-level planner (both modes).

Loaded from scenarios with yaml_load_typed (the `planner` key of the waypoints, path
following and panel tasks); systems/planning/acceleration_planner_math.py uses it.
"""

import math
from dataclasses import dataclass, field
from typing import Literal

from guidedarm.systems.config_checks import CheckFields, InRange, Positive, TextChoices
from guidedarm.systems.errors import ConfigurationError

# The fields only one mode reads (the rest both): a task refuses them set away from their
# defaults under the other mode (diagrams/tasks/waypoints/scenario.py).
ROBUST_ONLY_FIELDS = (
    "robust_recovery_rate",
    "damping_threshold",
    "max_damping",
    "bias_margin",
    "governor_gain",
    "velocity_bound_rate",
    "max_jerk",
    "approach_acceleration",
    "approach_rate",
    "joint_space_blend",
    "saturation_metric",
    "joint_limit_margin",
    "position_braking",
    "limit_blend",
    "handover_ramp",
    "max_reversal_rate",
    "stall_time",
)
PAPER_ONLY_FIELDS = ("scaling_recovery_rate", "min_singular_value")


@TextChoices
@dataclass
class PlannerConfig:
    """Gains and settings of the planner (defaults: the paper's values where it gives them).

    robust: the robust mode (default) or, False, the paper's law exactly as published (see
        systems/planning/acceleration_planner_math.py).
    gain_p: Lambda_P of (9) (1/s^2), equal on all six error axes.
    gain_v: Lambda_V of (9) (1/s), equal on all six error axes.
    neighbourhood_radius: epsilon of (19) (m).
    position_tolerance: TCP accuracy that ends the task (m).
    orientation_tolerance: the same for the orientation (rad; the largest Euler-angle
        error in the paper's mode, the rotation angle in the robust mode).
    velocity_threshold: theta of (14).
    penalty_strength: rho of (14) (rad/s^2 times the normalised velocity range); 0.003
        because (15) switches on with a step of c rho / (theta^2 range) in q'', which stays
        below the per-step change the scaling itself makes (< 0.07 rad/s^2 at 500 Hz on
        the paper's task), while a weaker barrier (rho = 0.001) is so stiff at 500 Hz that,
        unscaled, it chatters.
    scaling_recovery_rate: rate of the exponential return (18) of c to 1 (1/s), the
        paper's law's.
    robust_recovery_rate: the same in the robust mode (1/s), where c returns to 1 only
        after the smooth start and a braking fallback (the limits saturate joints instead
        of cutting c); faster than the paper's because max_jerk keeps the accelerations
        continuous however quickly c returns.
    stop_at_waypoints: stop at every waypoint instead of blending through it; the next
        elementary task starts once the TCP is within the tolerances and slower than
        rest_speed, i.e. practically at rest as boundary condition (3) asks.
    rest_speed: the TCP speed below which it counts as at rest (m/s).
    time_step: planner period (s, in [1e-4, 0.1]), 0.002 s = 500 Hz as UR servoJ.
    min_singular_value: the paper's mode stops with an error when the smallest singular
        value of J_g falls below it (m or rad per rad).
    blend_length: TCP path length (m) over which sigma of (19) goes from 0 to 1 once the
        TCP is inside a neighbourhood; the radius itself by default (the paper leaves the
        law open; docs/planner.md compares the choices against Table 2).
    damping_threshold: robust mode: the smallest singular value of J_g below which the
        damped inverse's lambda^2 rises from 0 (m or rad per rad).
    max_damping: robust mode: lambda at a singular J_g (lambda^2 = max_damping^2).
    bias_margin: robust mode: the fraction of the acceleration limits that
        a = -J^-1 Jdot qd may use before the speed governor brakes (below 1).
    governor_gain: robust mode: the governor's joint damping per unit of excess load (1/s).
    velocity_bound_rate: robust mode: near its limit a joint's acceleration is bounded by
        this rate times its distance to the velocity limit (1/s; at most 1 / time_step),
        capped at max_jerk / the largest acceleration limit so the jerk limit holds there.
    max_jerk: robust mode: the largest change of a commanded acceleration per second
        (rad/s^3); every step's q'' is reached from the last one at most this fast (the
        law, its saturation, the braking fallback and a task given while moving alike), so
        the accelerations stay continuous where the saturation or the step bounds would
        make them jump.
    approach_acceleration: robust mode: the fraction eta of the acceleration limits the
        approach to a target plans to brake with (0 keeps (9)'s exponential approach).
        (9) factors into (s + r0)(s + k) with r0 the slower root: e' tracks -r0 e at the
        rate k. The approach raises r0 to r(d) = sqrt(r0^2 + 2 / (d + 2 / (r_max^2 - r0^2)))
        with d = ||J^-1 e / (eta A)||_4 (s^2, A the acceleration limits): the speed a
        joint left u_i from the target may have while braking at eta A_i (the square-root
        law of time-optimal braking), r0 far from the target, r_max at it.
    approach_rate: robust mode: r_max of the approach (1/s), the exponential rate of the
        last millimetres.
    saturation_metric: robust mode: how a joint that would leave its bounds is saturated
        (SaturatedLeastSquares): "task", the others also make up its part of the TCP's
        acceleration in least squares (the Cartesian law where J is undamped; joint by
        joint where J is damped and once handed over to joint space); "joint", the others
        keep exactly their own share (a joint-by-joint clip). Neither scales the task for
        all joints.
    joint_space_blend: robust mode: [sigma_full, sigma_start]; as the smallest singular
        value of J_g falls from sigma_start to sigma_full the law hands over, smoothly, to
        the same error dynamics in joint space towards the waypoints' IK solutions, which
        crosses singularities a Cartesian law cannot.
    joint_limit_margin: robust mode, with acceleration limits: the commanded q stays within
        [lower + margin, upper - margin] of the plant's joint position limits (rad), and
        the waypoints' IK solutions too.
    position_braking: robust mode: the fraction of the acceleration limits a joint plans to
        brake with towards a position limit: its speed towards the limit is bounded by
        sqrt(2 position_braking A d), d the distance to the limit (the viability bound).
    limit_blend: robust mode: a joint closer than this to a position limit (rad, beyond the
        margin) and moving towards it hands the law over to joint space towards the
        waypoints' IK solutions for the rest of the task: the Cartesian line would leave
        the joint's range, the joint-space line between two configurations within the
        limits cannot.
    handover_ramp: robust mode: the time over which that hand-over blends in (s).
    max_reversal_rate: robust mode: the oscillation bound: a joint whose commanded
        acceleration reverses sign (between excursions beyond 50 % of its limit) more often
        than this (1/s, averaged over about 2 s) hands the law over to joint space for
        the rest of the task, and once handed over stops the planner with a PlanningError
        naming it.
    stall_time: robust mode: the planner stops with a PlanningError once the TCP has made
        no progress towards its target for this long (s); after half of it the law hands
        over to joint space first.
    """

    robust: bool = True
    gain_p: float = Positive(20.0)
    gain_v: float = Positive(9.392)
    neighbourhood_radius: float = Positive(0.05)
    position_tolerance: float = Positive(0.001)
    orientation_tolerance: float = Positive(0.001)
    velocity_threshold: float = InRange(0.0, 0.5, 0.1, low_open=True, high_open=True)
    penalty_strength: float = Positive(0.003)
    scaling_recovery_rate: float = Positive(1.0)
    robust_recovery_rate: float = Positive(3.0)
    stop_at_waypoints: bool = False
    rest_speed: float = Positive(0.001)
    time_step: float = InRange(1e-4, 0.1, 0.002)
    min_singular_value: float = Positive(0.01)
    blend_length: float = Positive(0.05)
    damping_threshold: float = Positive(0.03)
    max_damping: float = Positive(0.01)
    bias_margin: float = InRange(0.0, 1.0, 0.5, low_open=True, high_open=True)
    governor_gain: float = Positive(5.0)
    velocity_bound_rate: float = Positive(25.0)
    max_jerk: float = Positive(50.0)
    approach_acceleration: float = InRange(0.0, 1.0, 0.5, high_open=True)
    approach_rate: float = Positive(20.0)
    saturation_metric: Literal["task", "joint"] = "task"
    joint_space_blend: list[float] = field(default_factory=lambda: [0.005, 0.02])
    joint_limit_margin: float = InRange(0.0, 0.2, 0.01)
    position_braking: float = InRange(0.0, 1.0, 0.5, low_open=True, high_open=True)
    limit_blend: float = InRange(0.0, 1.0, 0.1)
    handover_ramp: float = Positive(0.3)
    max_reversal_rate: float = Positive(5.0)
    stall_time: float = Positive(3.0)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad setting."""
        CheckFields(self)
        low, high = (list(self.joint_space_blend) + [0.0, 0.0])[:2]
        if len(self.joint_space_blend) != 2 or not 0 <= low < high:
            raise ConfigurationError(
                "planner.joint_space_blend needs [sigma_full, sigma_start] with "
                f"0 <= sigma_full < sigma_start, got {self.joint_space_blend}"
            )
        if self.approach_acceleration > 0 and not (
            self.gain_v**2 >= 4 * self.gain_p and self.approach_rate > self.SlowRoot()
        ):
            raise ConfigurationError(
                "planner.approach_acceleration > 0 needs real roots of (9), gain_v^2 >= 4 "
                f"gain_p, and approach_rate above the slower one, got gain_p {self.gain_p}, "
                f"gain_v {self.gain_v}, approach_rate {self.approach_rate}"
            )
        if self.velocity_bound_rate * self.time_step > 1:
            raise ConfigurationError(
                f"planner.velocity_bound_rate must be at most 1 / time_step, got "
                f"{self.velocity_bound_rate}"
            )

    def SlowRoot(self) -> float:
        """r0 (1/s): the slower root of s^2 + gain_v s + gain_p, the rate at which (9)
        approaches a target (nan for complex roots)."""
        discriminant = self.gain_v**2 - 4 * self.gain_p
        return 0.5 * (self.gain_v - math.sqrt(discriminant)) if discriminant >= 0 else math.nan


def CheckModeFields(config: PlannerConfig, key: str = "planner") -> None:
    """Refuses (ConfigurationError, one line) a field of `config` set away from its default
    that config's mode does not read (ROBUST_ONLY_FIELDS, PAPER_ONLY_FIELDS); `key` is the
    config's place in the scenario, for the message."""
    defaults = PlannerConfig()
    mode, other = ("robust", "false") if config.robust else ("paper's", "true")
    for name in PAPER_ONLY_FIELDS if config.robust else ROBUST_ONLY_FIELDS:
        if getattr(config, name) != getattr(defaults, name):
            raise ConfigurationError(
                f"'{key}.{name}' has no effect with {key}.robust={str(config.robust).lower()}"
                f" (the {mode} mode does not read it): remove it or set {key}.robust={other}"
            )
