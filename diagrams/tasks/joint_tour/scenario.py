"""The `joint_tour` task's scenario (JointTourScenario)."""

from dataclasses import dataclass, field

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.config_checks import MAX_JOINT_POSITION, CheckFields, InRange, Positive
from guidedarm.systems.errors import ConfigurationError


@dataclass
class JointTourScenario:
    """arm: the arm of `station.arms` to move; waypoints: joint vectors (rad) visited after
    the arm's initial position, within its joint limits (and +-MAX_JOINT_POSITION);
    max_speed: joint speed cap (rad/s, in [0.05, 10]: the floor keeps each 4 pi move under
    400 s of simulated time); settle_time: time held at the end (s, <= 60);
    max_final_error: the run fails if the measured arm ends farther than this from the last
    waypoint on any joint (rad); max_tracking_error: the run fails if the measured arm is
    ever farther than this from the commanded tour on any joint (rad), at the delay
    (tracking.MAX_TRACKING_DELAY at most, reported as tracking_delay_s) that fits it best:
    a tour ends where it started, so the final error alone passes an arm that never moved
    (the shipped ur10e_joint_tour tracks within 0.0018 rad).
    random_seed: the scenario's random seed (the draw of station.errors)."""

    task: str = "joint_tour"
    arm: str = ""
    waypoints: list[list[float]] = InRange(-MAX_JOINT_POSITION, MAX_JOINT_POSITION, factory=list)
    max_speed: float = InRange(0.05, 10.0, 0.5)
    settle_time: float = InRange(0.0, 60.0, 0.5)
    max_final_error: float = Positive(0.01)
    max_tracking_error: float = Positive(0.05)
    random_seed: int = 0
    station: StationScenario = field(default_factory=StationScenario)

    def Validate(self) -> None:
        """Checked at load (CheckConfig): the fields' bounds, at least one waypoint, and
        `arm` one of station.arms."""
        CheckFields(self)
        if not self.waypoints:
            raise ConfigurationError("waypoints: at least one waypoint is needed")
        if self.arm not in self.station.arms:
            raise ConfigurationError(
                f"arm '{self.arm}' is not in station.arms {list(self.station.arms)}"
            )
