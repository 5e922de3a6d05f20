"""The `path_following` task's scenario (PathFollowingScenario) and the rules between its
keys, checked at load."""

from dataclasses import dataclass, field
from typing import Literal

from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.systems.config_checks import (
    ChangedKey,
    CheckFields,
    InRange,
    Positive,
    TextChoices,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.continuous_follower_math import ContinuousConfig
from guidedarm.systems.path_following.path_follower_math import Estimator, FollowerConfig
from guidedarm.systems.path_following.tool_pose_ik_math import ToolPoseIkConfig
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.planning.acceleration_planner_config import CheckModeFields
from guidedarm.systems.planning.acceleration_planner_math import PlannerConfig
from guidedarm.systems.scene.hose_geometry import RandomPathConfig

# How the arm is simulated: the station (servos, dynamics) or the kinematic station.
Executor = Literal["station", "kinematic"]
# How the arm moves between readings.
Motion = Literal["joint_trajectory", "planner", "continuous"]


@TextChoices
@dataclass
class PathFollowingScenario:
    """path: `paper_path_N`, another name in models/hoses/, or `random_<seed>`;
    path_csv: a centerline CSV (x, y, z in m, the arm's base frame; overrides path);
    workspace: the cell's walls (m, base frame), a box the hose and every moving body of
    the arm stay in; unset: the hose's own (models/hoses/NAME.yaml, or a NAME.yaml beside
    the CSV), else the paper's cell (x, y in [-0.55, 0.55], z >= 0.005);
    random_path: the region and shape of random paths (inside the workspace);
    estimator: the hose estimator of every reading, `grid` (the paper's) or `ranging`
    (the follower's automatic settings depend on it); random_seed: the scenario's random seed
    (the ToF noise); repeat_random_seed: when set, a second run with this random seed is
    overlaid (repeatability); executor: `station`
    or `kinematic`; motion: how the arm moves, `joint_trajectory` (rest-to-rest joint moves
    at tool_speed between the paper's steps), `planner` (those moves through Pajak et al.'s
    acceleration-level planner with the `planner` parameters) or `continuous` (no stops:
    sensing while moving, the target streamed through differential IK, with the
    `continuous` parameters); all within max_joint_speed and max_joint_acceleration;
    period: follower and IK tick of the stop-and-go modes (s); max_time: simulated time
    limit (s); min_coverage: success threshold; follower: the algorithm's parameters;
    ik: IK tolerances; arm, gripper_frame, tof: names in the station; base_frame: the arm's
    base frame B (scoped name; empty: `<arm>::base`).
    tool_speed: the tool's speed in joint moves (m/s); max_joint_speed: joint speed limit
    (rad/s); max_joint_acceleration: joint acceleration limit (rad/s^2).
    tool_roll_deg: the tool's roll about the hose's tangent x_T (deg), held by the start
    pose and both followers' targets; 0: the paper's (z_T in the vertical plane through
    x_T, the row sensors looking down); -45 lifts both arms above the hose's centre, for
    a hose on the table (a roll putting the tool below the workspace floor along the
    hose is refused). ignore_table: readings at the range of the table top (world z = 0,
    known_surfaces) are not hose; false: every reading may be."""

    task: str = "path_following"
    path: str = "paper_path_1"
    path_csv: str = ""
    workspace: WorkspaceConfig | None = None
    random_path: RandomPathConfig = field(default_factory=RandomPathConfig)
    estimator: Estimator = "grid"
    random_seed: int = 0
    repeat_random_seed: int | None = None
    executor: Executor = "station"
    tool_speed: float = Positive(0.05)
    max_joint_speed: float = Positive(1.0)
    max_joint_acceleration: float = Positive(5.0)
    motion: Motion = "joint_trajectory"
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    continuous: ContinuousConfig = field(default_factory=ContinuousConfig)
    period: float = Positive(0.01)
    max_time: float = Positive(400.0)
    min_coverage: float = InRange(0.0, 1.0, 0.95)
    tool_roll_deg: float = InRange(-180.0, 180.0, 0.0)
    ignore_table: bool = True
    follower: FollowerConfig = field(default_factory=FollowerConfig)
    ik: ToolPoseIkConfig = field(default_factory=ToolPoseIkConfig)
    arm: str = "mz04d"
    base_frame: str = ""
    gripper_frame: str = "gripper::gripper"
    tof: str = "tof"
    station: StationScenario = field(default_factory=StationScenario)

    def Validate(self) -> None:
        """Checked at load (CheckConfig): the fields' bounds, then the rules between the
        keys (CheckScenarioRules: the arm and ToF tool in the station, keys the
        chosen motion or executor would not read)."""
        CheckFields(self)
        CheckScenarioRules(self)


def CheckScenarioRules(scenario: PathFollowingScenario) -> None:
    """The rules between the scenario's keys (PathFollowingScenario.Validate, after the
    fields' bounds)."""
    if scenario.arm not in scenario.station.arms or scenario.tof not in scenario.station.tof_tools:
        raise ConfigurationError(
            f"station must define arms.{scenario.arm} and tof_tools.{scenario.tof}"
        )
    _CheckMotionKeys(scenario)
    _CheckExecutorKeys(scenario)
    if scenario.motion == "planner":
        CheckModeFields(scenario.planner)
    if scenario.motion == "continuous":
        _CheckContinuousReadings(scenario)
    arm = scenario.station.arms[scenario.arm]
    if scenario.motion == "continuous" and scenario.continuous.servo_period < arm.control_period:
        raise ConfigurationError(
            f"continuous.servo_period ({scenario.continuous.servo_period} s) is shorter than "
            f"station.arms.{scenario.arm}.control_period ({arm.control_period} s), the period "
            "at which the arm takes commands"
        )
    period = scenario.continuous.servo_period
    if scenario.motion == "continuous" and arm.control_period not in (
        period,
        ArmConfig().control_period,
    ):
        # Left at its default, the arm's control period becomes the servo's (setup).
        raise ConfigurationError(
            f"station.arms.{scenario.arm}.control_period ({arm.control_period} s) must equal "
            f"continuous.servo_period ({period} s) with motion=continuous (or be left unset): "
            "the arm's controller samples the servo's stream, and a command held over several "
            "samples reads as velocity steps"
        )


def _CheckContinuousReadings(scenario: PathFollowingScenario) -> None:
    """The hose fit needs min_fit_points readings within fit_length of hose: at the cruise
    speed the ToF tool reads one every speed x period (m), so a faster cruise would leave
    the fit without its tangent, and the speed setting would only mislead."""
    c, period = scenario.continuous, scenario.station.tof_tools[scenario.tof].period
    fastest = c.fit_length / (c.min_fit_points * period)
    if not c.speed <= fastest:
        raise ConfigurationError(
            f"continuous.speed ({c.speed:g} m/s) is faster than the hose fit can follow: "
            f"continuous.fit_length ({c.fit_length:g} m) must hold continuous.min_fit_points "
            f"({c.min_fit_points}) readings, one every {period:g} s from the ToF tool, so "
            f"at most {fastest:.3g} m/s"
        )


# Keys that only some motions read: set to anything but their default under another motion
# they would be ignored, so they are refused. The stop-and-go IK's step limits (ik.*
# below) are lifted for the start pose, which every motion solves with the other ik keys.
_STOP_AND_GO = ("joint_trajectory", "planner")
_MOTION_KEYS = {
    "tool_speed": _STOP_AND_GO,
    "period": _STOP_AND_GO,
    "follower": _STOP_AND_GO,
    "ik.max_swing": _STOP_AND_GO,
    "ik.max_step_rotation_deg": _STOP_AND_GO,
    "ik.shortfall_tolerance_deg": _STOP_AND_GO,
    "planner": ("planner",),
    "continuous": ("continuous",),
}


def _CheckMotionKeys(scenario: PathFollowingScenario) -> None:
    """Refuses a key set away from its default that scenario.motion does not read."""
    defaults = type(scenario)()
    for key, motions in _MOTION_KEYS.items():
        if scenario.motion in motions:
            continue
        changed = ChangedKey(_Dotted(scenario, key), _Dotted(defaults, key), key)
        if changed:
            raise ConfigurationError(
                f"'{changed}' has no effect with motion={scenario.motion} (it is read only "
                f"with motion={' or '.join(motions)}): remove it or change motion"
            )


def _CheckExecutorKeys(scenario: PathFollowingScenario) -> None:
    """Refuses, with executor=kinematic, cell errors and a servo gain, plant, visualization
    or camera setting set away from its default: the kinematic station poses the nominal
    cell's arm where it is commanded (no servo, no dynamics, nothing drawn in Meshcat, no
    camera rendered) and reads none of them."""
    if scenario.executor != "kinematic":
        return
    if scenario.station.HasErrors():
        raise ConfigurationError(
            "station.errors and station.errors_preset have no effect with executor=kinematic "
            "(it poses the nominal cell where the arm is commanded): remove them or use "
            "executor=station"
        )
    arm, default_arm = scenario.station.arms[scenario.arm], ArmConfig()
    prefix = f"station.arms.{scenario.arm}"
    for key, value, default in (
        ("station.plant_config", scenario.station.plant_config, StationScenario().plant_config),
        ("station.visualization", scenario.station.visualization, StationScenario().visualization),
        ("station.cameras", scenario.station.cameras, StationScenario().cameras),
        (f"{prefix}.kp", arm.kp, default_arm.kp),
        (f"{prefix}.kd", arm.kd, default_arm.kd),
    ):
        changed = ChangedKey(value, default, key)
        if changed:
            raise ConfigurationError(
                f"'{changed}' has no effect with executor=kinematic (it poses the arm where "
                "it is commanded: no servo, no dynamics, no Meshcat, no camera): remove it or use "
                "executor=station"
            )


def _Dotted(config: object, key: str) -> object:
    """The value of a dotted key (`ik.max_swing`) of a config tree."""
    for name in key.split("."):
        config = getattr(config, name)
    return config
