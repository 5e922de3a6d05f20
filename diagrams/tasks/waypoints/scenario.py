"""The `waypoints` task's scenario (WaypointsScenario) and the keys a run would not read."""

from dataclasses import dataclass, field

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.config_checks import CheckFields, NonNegative, Positive
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.planning.acceleration_planner_config import CheckModeFields
from guidedarm.systems.planning.acceleration_planner_math import PlannerConfig

LIMIT_CHOICES = ("none", "velocity", "velocity,acceleration")


@dataclass
class WaypointsScenario:
    """arm: the arm of `station.arms` to move; base_frame, tool_frame: scoped frame names
    (e.g. `ur10e::base`, `ur10e::tool0`) of the base B and the TCP T.
    waypoints: rows [x, y, z, roll, pitch, yaw] of T in B (m, rad, Z-Y-X Euler angles); the
        last one is the final location. The start is the arm's initial position.
    limits: which of the paper's constraints are on: none, velocity, velocity,acceleration.
    max_joint_velocity, max_joint_acceleration: symmetric limits (rad/s, rad/s^2), one
        value for every joint or one per joint.
    planner: the planner's gains and settings. max_time: the run fails if the task has not
        ended by then (s); settle_time: simulated after the end (s).
    max_tracking_error: the run fails if the measured TCP is ever farther than this from
        the commanded one (m), at the delay (tracking.MAX_TRACKING_DELAY at most, reported
        as tracking_delay_s) that fits the measurement best: the planner's success alone
        says nothing of the arm.
    random_seed: the scenario's random seed (the draw of station.errors).
    """

    task: str = "waypoints"
    arm: str = ""
    base_frame: str = ""
    tool_frame: str = ""
    waypoints: list[list[float]] = field(default_factory=list)
    limits: str = "velocity,acceleration"
    max_joint_velocity: list[float] = Positive(factory=lambda: [1.0471975511965976])
    max_joint_acceleration: list[float] = Positive(factory=lambda: [1.3962634015954636])
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    max_time: float = Positive(20.0)
    settle_time: float = NonNegative(0.3)
    max_tracking_error: float = Positive(0.01)
    random_seed: int = 0
    station: StationScenario = field(default_factory=StationScenario)

    def Validate(self) -> None:
        """Checked at load (CheckConfig): the fields' bounds, `limits` one of LIMIT_CHOICES,
        at least one waypoint, and no key set that the run would not read
        (CheckReadKeys)."""
        CheckFields(self)
        if self.limits not in LIMIT_CHOICES:
            raise ConfigurationError(f"limits must be one of {LIMIT_CHOICES}, got '{self.limits}'")
        if not self.waypoints:
            raise ConfigurationError("waypoints: at least one waypoint is needed")
        CheckReadKeys(self)


def CheckReadKeys(scenario: WaypointsScenario) -> None:
    """Refuses a key set away from its default that the run would not read: a planner
    field of the other mode (CheckModeFields), or a joint limit that
    `limits` switches off."""
    CheckModeFields(scenario.planner)
    scenario_defaults = WaypointsScenario()
    for key, needs in (("max_joint_velocity", "velocity"), ("max_joint_acceleration", "accel")):
        changed = getattr(scenario, key) != getattr(scenario_defaults, key)
        if changed and needs not in scenario.limits:
            raise ConfigurationError(
                f"'{key}' has no effect with limits={scenario.limits}: remove it or switch "
                "the limit on (limits=velocity or velocity,acceleration)"
            )
