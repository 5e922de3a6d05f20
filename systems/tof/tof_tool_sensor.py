"""ToFToolSensor: six VL6180X-like time-of-flight sensors reading SceneGraph geometry.

The ray casting, noise and drift live in tof_tool_sensor_math.py, the detection grid in
detection_grid.py. The outputs are what the tool's microcontroller streams, so the hardware
driver can produce the same ports: the six ranges (m), their validity flags (1 = a return
within range, 0 = none) and their measurement instants (s, diagram time), by which a moving
consumer looks up the tool's pose when a range was taken.
"""

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import QueryObject
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from guidedarm.systems.cell_errors.distributions import DrawErrors
from guidedarm.systems.config_checks import (
    CheckFields,
    CheckInstance,
    CheckVector,
    InRange,
    NonNegative,
    Positive,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.plant_frames import CheckPlant, GetScopedFrame
from guidedarm.systems.tof.detection_grid import DetectionGrid
from guidedarm.systems.tof.primitive_ray_casting import SceneRayCaster, SensorMount
from guidedarm.systems.tof.tof_errors import ErrorReadings, ToFErrors
from guidedarm.systems.tof.tof_tool_sensor_math import (
    CalibratedRanges,
    ConeRays,
    DriftStep,
    Measure,
    SeededGenerator,
)

NUM_SENSORS = 6
# The radius of the paper's 20 mm shower hose (m).
DEFAULT_TARGET_RADIUS = 0.010


def _default_frames() -> list[str]:
    return [f"tof_tool::tof_sensor_{i}" for i in range(1, NUM_SENSORS + 1)]


@dataclass
class ToFToolConfig:
    """A six-sensor ToF tool; ports `<name>.ranges`, `.valid`, `.measured_at` and the grid's.

    sensor_frames: scoped frames of sensors 1..6 (+z = line of sight); 1-3 are the grid rows.
    tool_frame: the tool frame T (centre O of the detection field).
    cone_angle_deg: vertex angle of each sensor's cone; max_range: no return beyond it (m).
    target_radius: radius of the round target (the hose) that the detection grid's
        consistency check assumes (m); 0: the station hose's radius
        (StationScenario.ToFTool), DEFAULT_TARGET_RADIUS without a hose.
    noise_std, quantization: Gaussian noise and resolution of a reading (m).
    seed: seed of the noise generator; None: 0 (path following fills in its `seed`).
    period: a new range every period (s); range k is available at k period.
    ranging_time: each range integrates over the ranging_time (s) before it is available;
        its measurement instant is the middle of that interval (the VL6180X ranges in
        about 10 ms). At most `period`.
    rings: rings of rays sampling each cone (1 + 3 rings (rings + 1) rays; at most 20,
        1261 rays a sensor: each reading casts every ray).
    calibration_file: the sensors' calibrated offsets, a tof_offsets.yaml written by
        `guidedarm calibrate tof` (relative to models/ or absolute; '' none): its six
        `offset` values (m) are subtracted from every valid reading, by the simulated
        sensor and by the hardware driver alike.
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
    ranging_time: float = NonNegative(0.010)
    rings: int = InRange(0, 20, 2)
    calibration_file: str = ""

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        if len(self.sensor_frames) != NUM_SENSORS:
            raise ConfigurationError(f"sensor_frames must name {NUM_SENSORS} frames")
        if not self.ranging_time <= self.period:
            raise ConfigurationError(
                f"ranging_time ({self.ranging_time} s) must not exceed period ({self.period} s)"
            )

    def TargetRadius(self) -> float:
        """The target radius in use (m): target_radius, or DEFAULT_TARGET_RADIUS for 0."""
        return self.target_radius or DEFAULT_TARGET_RADIUS


# Output ports of a ToF tool, the same in the simulated and the hardware station.
TOF_PORTS = ("ranges", "valid", "measured_at", "detections", "detection_errors")

# A reading in the discrete state: ranges (6, m), valid (6), measured_at (6, s) and the
# time it becomes available (s).
_RANGES, _VALID, _MEASURED_AT = (slice(k * NUM_SENSORS, (k + 1) * NUM_SENSORS) for k in range(3))
_AVAILABLE_AT = 3 * NUM_SENSORS
# Equal event times computed in two ways differ by rounding only.
_TIME_TOLERANCE = 1e-9


def _NoReading(max_range: float) -> np.ndarray:
    return np.r_[np.full(NUM_SENSORS, max_range), np.zeros(NUM_SENSORS), -np.ones(7)]


class ToFToolSensor(LeafSystem):
    """Ranges of six ToF sensors from the `query_object` input (SceneGraph's QueryObject).

    Timing: range k (k = 1, 2, ...) integrates over [k period - ranging_time, k period];
    a periodic discrete update at its measurement instant k period - ranging_time / 2 reads
    the geometry once and holds it; the outputs at time t show the newest range available
    at t (so a consumer ticking at k period sees range k). Range 0 is read from the
    geometry at the start (an initialization event), available at once.
    Outputs: `ranges` (6, m; max_range where there is no return), `valid` (6, 0 or 1),
    `measured_at` (6, s: the measurement instant of each sensor's current range, -1 before
    the first) and the paper's 3 x 3 grid of that reading: `detections` and
    `detection_errors` (9 each, 0 or 1, row-major: row sensor i = 1..3, column sensor
    j = 4..6; tof_sensing).
    A return reads what `errors` (ToFErrors, drawn) make of the true range (ErrorReadings:
    crosstalk, offset, drift), plus noise from
    np.random.default_rng((seed, k)) for range k, quantised. The drift (a reflected random
    walk, see DriftStep) advances once a period from np.random.default_rng((seed, k, 1)).
    Geometry of the tool's own model instance is not seen (its cones look away from it by
    construction).
    """

    def __init__(
        self,
        plant: MultibodyPlant,
        config: ToFToolConfig,
        errors: ToFErrors | None = None,
        calibration_offset: np.ndarray | None = None,
    ) -> None:
        """plant: a finalized plant registered with the SceneGraph whose QueryObject the
        `query_object` input carries (the station's); errors: the tool's drawn ToFErrors
        (None: an exact tool); calibration_offset: six offsets (m) subtracted from every
        valid reading (config.calibration_file's; None: none); bad arguments raise
        ConfigurationError naming them."""
        super().__init__()
        CheckPlant("plant", plant, scene_graph=True)
        CheckInstance("config", config, ToFToolConfig)
        config.Validate()
        errors = DrawErrors(errors or ToFErrors(), None, "errors")
        errors.Validate()
        self._config = config
        self._errors = errors
        # The noise and drift generator, set to each reading's seed (SeededGenerator).
        self._generator = np.random.Generator(np.random.PCG64())
        self._calibration = CheckVector(
            "calibration_offset",
            np.zeros(NUM_SENSORS) if calibration_offset is None else calibration_offset,
            NUM_SENSORS,
        )
        frames = [GetScopedFrame(plant, name, "tof sensor_frames") for name in config.sensor_frames]
        instance = frames[0].model_instance()
        ignored = {
            g
            for b in plant.GetBodyIndices(instance)
            for g in plant.GetCollisionGeometriesForBody(plant.get_body(b))
        }
        self._caster = SceneRayCaster(
            ConeRays(np.radians(config.cone_angle_deg), config.rings),
            config.max_range,
            frozenset(ignored),
            MakeSensorMount(plant, config),
        )
        self._query_port = self.DeclareAbstractInputPort(
            "query_object", AbstractValue.Make(QueryObject())
        )
        # The newest reading (pending) and the one before it (published): the output
        # shows pending from its availability time on.
        self._published = self.DeclareDiscreteState(_NoReading(config.max_range))
        self._pending = self.DeclareDiscreteState(_NoReading(config.max_range))
        self._drift = self.DeclareDiscreteState(NUM_SENSORS)
        self.DeclareInitializationDiscreteUpdateEvent(self._Initialize)
        self.DeclarePeriodicDiscreteUpdateEvent(
            config.period, config.period - config.ranging_time / 2, self._Measure
        )
        depends = {self.time_ticket(), self.xd_ticket()}
        self.DeclareVectorOutputPort("ranges", NUM_SENSORS, self._Output(_RANGES), depends)
        self.DeclareVectorOutputPort("valid", NUM_SENSORS, self._Output(_VALID), depends)
        self.DeclareVectorOutputPort(
            "measured_at", NUM_SENSORS, self._Output(_MEASURED_AT), depends
        )
        DeclareGridOutputs(self, MakeDetectionGrid(plant, config), self._Reading, depends)

    def Caster(self) -> SceneRayCaster:
        """The ray caster of the six cones."""
        return self._caster

    def SensorPosesInWorld(self, context: Context) -> list[RigidTransform]:
        """X_WS of the six sensors."""
        return self._caster.MountedPoses(self._query_port.Eval(context))

    def TrueRanges(self, context: Context) -> np.ndarray:
        """Noise-free nearest returns at the context's time (m; inf when nothing is in
        range)."""
        return self._caster.MountedRanges(self._query_port.Eval(context))

    def _Read(self, context: Context, k: int, drift: np.ndarray) -> np.ndarray:
        """Range k from the geometry at the context's time, as a state reading."""
        c = self._config
        t = context.get_time()
        rng = SeededGenerator(self._generator, (c.seed or 0, k))
        readings = ErrorReadings(self.TrueRanges(context), self._errors, drift)
        ranges, valid = Measure(readings, rng, c.noise_std, c.quantization, c.max_range)
        ranges = CalibratedRanges(ranges, valid, self._calibration)
        available = k * c.period if k * c.period > t else t
        return np.concatenate([ranges, valid, np.full(NUM_SENSORS, t), [available]])

    def _Initialize(self, context: Context, state: DiscreteValues) -> None:
        k = int(np.floor(context.get_time() / self._config.period + _TIME_TOLERANCE))
        drift = context.get_discrete_state(self._drift).value()
        state.set_value(self._pending, self._Read(context, k, drift))

    def _Measure(self, context: Context, state: DiscreteValues) -> None:
        c, e = self._config, self._errors
        k = round((context.get_time() + c.ranging_time / 2) / c.period)
        drift = context.get_discrete_state(self._drift).value()
        if e.drift_rate > 0:
            rng = SeededGenerator(self._generator, (c.seed or 0, k, 1))
            drift = DriftStep(drift, rng, e.drift_rate, c.period, e.drift_max)
            state.set_value(self._drift, drift)
        state.set_value(self._published, context.get_discrete_state(self._pending).value())
        state.set_value(self._pending, self._Read(context, k, drift))

    def _Current(self, context: Context) -> np.ndarray:
        """The newest reading available at the context's time."""
        pending = context.get_discrete_state(self._pending).value()
        if context.get_time() >= pending[_AVAILABLE_AT] - _TIME_TOLERANCE:
            return pending
        return context.get_discrete_state(self._published).value()

    def _Reading(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        reading = self._Current(context)
        return reading[_RANGES], reading[_VALID] > 0.5

    def _Output(self, part: slice):
        def calc(context: Context, output: BasicVector) -> None:
            output.SetFromVector(self._Current(context)[part])

        return calc


def MakeSensorMount(plant: MultibodyPlant, config: ToFToolConfig) -> SensorMount:
    """The sensors' mount on the (finalized) plant's tool body B: B's SceneGraph frame and
    X_BS. Raises ConfigurationError for a sensor frame not welded to B."""
    config.Validate()
    context = plant.CreateDefaultContext()
    body = GetScopedFrame(plant, config.tool_frame, "tof tool_frame").body()
    welded = {b.index() for b in plant.GetBodiesWeldedTo(body)}
    X_BS = []
    for name in config.sensor_frames:
        frame = GetScopedFrame(plant, name, "tof sensor_frames")
        if frame.body().index() not in welded:
            raise ConfigurationError(
                f"tof sensor frame {name} must be welded to the tool frame's body {body.name()}"
            )
        X_BS.append(frame.CalcPose(context, body.body_frame()))
    return SensorMount(plant.GetBodyFrameIdOrThrow(body.index()), tuple(X_BS))


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
