"""PlannerConfig: the gains and settings of the acceleration-level planner (both modes).

Loaded from scenarios with yaml_load_typed (the `planner` key of the waypoints, path
following and panel tasks); systems/planning/acceleration_planner_math.py uses it.
"""

from dataclasses import dataclass, field

import numpy as np

from guidedarm.systems.errors import ConfigurationError


@dataclass
class PlannerConfig:
    """Gains and settings of the planner (defaults: the seed's values where it gives them).

    robust: the robust mode (default) or, False, the seed's law exactly as published (see
        the module docstring).
    gain_p, gain_v: Lambda_P (1/s^2) and Lambda_V (1/s), equal on all six error axes.
    neighbourhood_radius: epsilon of (19) (m). position_tolerance: TCP accuracy that ends
        the task (m); orientation_tolerance: the same for the orientation (rad; the largest
        Euler-angle error in the seed's mode, the rotation angle in the robust mode).
    velocity_threshold: theta of (14). penalty_strength: rho of (14) (rad/s^2 times the
        normalised velocity range); 0.003 because (15) switches on with a step of
        c rho / (theta^2 range) in q'', which stays below the per-step change the
        scaling itself makes (< 0.07 rad/s^2 at 500 Hz on the seed's task), while a
        weaker barrier (rho = 0.001) is so stiff at 500 Hz that, unscaled, it chatters.
    scaling_recovery_rate: rate of the exponential return (18) of c to 1 (1/s).
    stop_at_waypoints: stop at every waypoint instead of blending through it; the next
        elementary task starts once the TCP is within the tolerances and slower than
        rest_speed (m/s), i.e. practically at rest as boundary condition (3) asks.
    time_step: planner period (s), 0.002 s = 500 Hz as UR servoJ.
    min_singular_value: the seed's mode stops with an error when the smallest singular
        value of J_g falls below it (m or rad per rad).
    blend_length: TCP path length (m) over which sigma of (19) goes from 0 to 1 once the
        TCP is inside a neighbourhood; the radius itself by default (the seed leaves the
        law open; docs/planner.md compares the choices against Table 2).
    Robust mode only: damping_threshold, max_damping: the damped inverse's lambda^2 rises
        from 0 at the smallest singular value damping_threshold to max_damping^2 at 0;
        bias_margin: the fraction of the acceleration limits that a = -J^-1 Jdot qd may
        use before the speed governor brakes; governor_gain: its damping per unit of
        excess load (1/s); joint_space_blend: [sigma_full, sigma_start]: as the smallest
        singular value of J_g falls from sigma_start to sigma_full the law hands over,
        smoothly, to the same error dynamics in joint space towards the waypoints' IK
        solutions, which crosses singularities a Cartesian law cannot.
    """

    robust: bool = True
    gain_p: float = 20.0
    gain_v: float = 9.392
    neighbourhood_radius: float = 0.05
    position_tolerance: float = 0.001
    orientation_tolerance: float = 0.001
    velocity_threshold: float = 0.1
    penalty_strength: float = 0.003
    scaling_recovery_rate: float = 1.0
    stop_at_waypoints: bool = False
    rest_speed: float = 0.001
    time_step: float = 0.002
    min_singular_value: float = 0.01
    blend_length: float = 0.05
    damping_threshold: float = 0.03
    max_damping: float = 0.01
    bias_margin: float = 0.5
    governor_gain: float = 5.0
    joint_space_blend: list[float] = field(default_factory=lambda: [0.005, 0.02])

    def Validate(self) -> None:
        """Raises ConfigurationError for non-positive gains or settings."""
        for name in (
            "gain_p",
            "gain_v",
            "neighbourhood_radius",
            "position_tolerance",
            "orientation_tolerance",
            "velocity_threshold",
            "penalty_strength",
            "scaling_recovery_rate",
            "time_step",
            "min_singular_value",
            "blend_length",
            "rest_speed",
            "damping_threshold",
            "max_damping",
            "bias_margin",
            "governor_gain",
        ):
            value = getattr(self, name)
            if not np.isfinite(value) or value <= 0:
                raise ConfigurationError(f"planner.{name} must be positive, got {value}")
        low, high = (list(self.joint_space_blend) + [0.0, 0.0])[:2]
        if len(self.joint_space_blend) != 2 or not 0 <= low < high:
            raise ConfigurationError(
                "planner.joint_space_blend needs [sigma_full, sigma_start] with "
                f"0 <= sigma_full < sigma_start, got {self.joint_space_blend}"
            )
        if self.bias_margin >= 1:
            raise ConfigurationError(f"planner.bias_margin must be below 1, got {self.bias_margin}")
