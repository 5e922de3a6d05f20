"""ToFToolSensor: six VL6180X-like time-of-flight sensors reading SceneGraph geometry.

The ray casting, noise and detection grid live in tof_tool_sensor_math.py. The outputs are
what the tool's microcontroller streams, so the hardware driver can produce the same ports:
the six ranges (m) and their validity flags (1 = a return within range, 0 = none).
"""

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import QueryObject
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context, LeafSystem, ValueProducer

from guidedarm.systems.config_checks import CheckFields, InRange, NonNegative, Positive
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.plant_frames import GetScopedFrame
from guidedarm.systems.tof.tof_tool_sensor_math import ConeRays, DetectionGrid, Measure, RayCaster

NUM_SENSORS = 6
# The radius of the paper's 20 mm shower hose (m).
DEFAULT_TARGET_RADIUS = 0.010


def _default_frames() -> list[str]:
    return [f"tof_tool::tof_sensor_{i}" for i in range(1, NUM_SENSORS + 1)]


@dataclass
class ToFToolConfig:
    """A six-sensor ToF tool; ports `<name>.ranges` and `<name>.valid`.

    sensor_frames: scoped frames of sensors 1..6 (+z = line of sight); 1-3 are the grid rows.
    tool_frame: the tool frame T (centre O of the detection field).
    cone_angle_deg: vertex angle of each sensor's cone; max_range: no return beyond it (m).
    target_radius: radius of the round target (the hose) that the detection grid's
        consistency check assumes (m); 0: the followed hose's (path following fills it in
        from station.hose.diameter), DEFAULT_TARGET_RADIUS for a sensor on its own.
    noise_std, quantization: Gaussian noise and resolution of a reading (m).
    seed: seed of the noise generator; None: 0 (path following fills in its `seed`).
    period: the noise is redrawn every period (s).
    rings: rings of rays sampling each cone (1 + 3 rings (rings + 1) rays).
    """

    sensor_frames: list[str] = field(default_factory=_default_frames)
    tool_frame: str = "tof_tool::tof_tool"
    cone_angle_deg: float = InRange(0.0, 180.0, 25.0, low_open=True, high_open=True)
    max_range: float = Positive(0.100)
    target_radius: float = NonNegative(0.0)
    noise_std: float = NonNegative(0.002)
    quantization: float = NonNegative(0.001)
    seed: int | None = None
    period: float = Positive(0.02)
    rings: int = 2

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        if len(self.sensor_frames) != NUM_SENSORS:
            raise ConfigurationError(f"sensor_frames must name {NUM_SENSORS} frames")

    def TargetRadius(self) -> float:
        """The target radius in use (m): target_radius, or DEFAULT_TARGET_RADIUS for 0."""
        return self.target_radius or DEFAULT_TARGET_RADIUS


# Output ports of a ToF tool, the same in the simulated and the hardware station.
TOF_PORTS = ("ranges", "valid", "detections", "detection_errors")


class ToFToolSensor(LeafSystem):
    """Ranges of six ToF sensors from the `query_object` input (SceneGraph's QueryObject).

    Output `ranges` (6, m; max_range where there is no return) and `valid` (6, 0 or 1), and
    the paper's 3 x 3 grid of that reading: `detections` and `detection_errors` (9 each,
    0 or 1, row-major: row sensor i = 1..3, column sensor j = 4..6; tof_sensing).
    The noise of a reading at time t comes from np.random.default_rng((seed, floor(t /
    period))), so a run is reproducible and `seed` changes it. Geometry of the tool's own
    model instance is not seen (its cones look away from it by construction).
    """

    def __init__(self, plant: MultibodyPlant, config: ToFToolConfig) -> None:
        super().__init__()
        config.Validate()
        self._config = config
        frames = [GetScopedFrame(plant, name, "tof sensor_frames") for name in config.sensor_frames]
        self._frame_ids = [plant.GetBodyFrameIdOrThrow(f.body().index()) for f in frames]
        self._X_BS = [f.GetFixedPoseInBodyFrame() for f in frames]
        instance = frames[0].model_instance()
        ignored = {
            g
            for b in plant.GetBodyIndices(instance)
            for g in plant.GetCollisionGeometriesForBody(plant.get_body(b))
        }
        self._caster = RayCaster(
            ConeRays(np.radians(config.cone_angle_deg), config.rings),
            config.max_range,
            frozenset(ignored),
        )
        self._query_port = self.DeclareAbstractInputPort(
            "query_object", AbstractValue.Make(QueryObject())
        )
        self._reading = self.DeclareCacheEntry(
            "reading",
            ValueProducer(
                allocate=lambda: AbstractValue.Make(np.zeros(2 * NUM_SENSORS)),
                calc=self._CalcReading,
            ),
            prerequisites_of_calc={self.time_ticket(), self._query_port.ticket()},
        )
        self.DeclareVectorOutputPort(
            "ranges", NUM_SENSORS, self.CalcRanges, prerequisites_of_calc={self._reading.ticket()}
        )
        self.DeclareVectorOutputPort(
            "valid", NUM_SENSORS, self.CalcValid, prerequisites_of_calc={self._reading.ticket()}
        )
        DeclareGridOutputs(
            self, MakeDetectionGrid(plant, config), self._Reading, {self._reading.ticket()}
        )

    def SensorPosesInWorld(self, context: Context) -> list[RigidTransform]:
        """X_WS of the six sensors."""
        query = self._query_port.Eval(context)
        return [
            query.GetPoseInWorld(f) @ X for f, X in zip(self._frame_ids, self._X_BS, strict=True)
        ]

    def TrueRanges(self, context: Context) -> np.ndarray:
        """Noise-free nearest returns (m; inf when nothing is in range)."""
        query = self._query_port.Eval(context)
        poses = self.SensorPosesInWorld(context)
        return np.array([self._caster.Range(query, X_WS) for X_WS in poses])

    def _CalcReading(self, context: Context, value: AbstractValue) -> None:
        c = self._config
        tick = int(np.floor(context.get_time() / c.period + 1e-9))
        rng = np.random.default_rng((c.seed or 0, tick))
        ranges, valid = Measure(
            self.TrueRanges(context), rng, c.noise_std, c.quantization, c.max_range
        )
        value.set_value(np.concatenate([ranges, valid.astype(float)]))

    def _Reading(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        reading = self._reading.Eval(context)
        return reading[:NUM_SENSORS], reading[NUM_SENSORS:] > 0.5

    def CalcRanges(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._reading.Eval(context)[:NUM_SENSORS])

    def CalcValid(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._reading.Eval(context)[NUM_SENSORS:])


def MakeDetectionGrid(plant: MultibodyPlant, config: ToFToolConfig) -> DetectionGrid:
    """The tool's detection grid from the (finalized) plant's tool and sensor frames."""
    config.Validate()
    context = plant.CreateDefaultContext()
    T = GetScopedFrame(plant, config.tool_frame, "tof tool_frame")
    X_TS = tuple(
        GetScopedFrame(plant, name, "tof sensor_frames").CalcPose(context, T)
        for name in config.sensor_frames
    )
    return DetectionGrid(X_TS, config.TargetRadius(), np.radians(config.cone_angle_deg))


def DeclareGridOutputs(
    system: LeafSystem,
    grid: DetectionGrid,
    reading: Callable[[Context], tuple[np.ndarray, np.ndarray]],
    prerequisites: set,
) -> None:
    """Declares `detections` and `detection_errors` (9, row-major) of `system`, computed
    by `grid` from reading(context) = (ranges, valid), which depends on prerequisites."""

    def calc(index: int):
        def output(context: Context, value: BasicVector) -> None:
            value.SetFromVector(grid.Detect(*reading(context))[index].ravel().astype(float))

        return output

    system.DeclareVectorOutputPort("detections", 9, calc(0), prerequisites_of_calc=prerequisites)
    system.DeclareVectorOutputPort(
        "detection_errors", 9, calc(1), prerequisites_of_calc=prerequisites
    )
