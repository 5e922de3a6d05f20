"""Task `joint_tour`: move an arm of the station through joint-space waypoints.

The smallest complete use of the station: a cubic joint trajectory, timed so that no
joint exceeds the given speed, feeds `<arm>.position_commanded`; the run reports how
closely the simulated servo tracked it.
"""

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial

from guidedarm.diagrams.overlays.joint_tour_overlays import AddJointTourOverlays
from guidedarm.diagrams.plots import PlotJointSeries
from guidedarm.diagrams.run_context import AdvanceWithProgress, RunContext
from guidedarm.diagrams.station.station import MakeStation, TrueArmPositions
from guidedarm.diagrams.station.station_plant import (
    ArmInitialPosition,
    CheckJointPositions,
    MakeMultibodyPlant,
)
from guidedarm.diagrams.tasks.common.start_pose import CheckArmAtStart
from guidedarm.diagrams.tasks.common.tracking import DelayedTrackingError
from guidedarm.diagrams.tasks.common.trajectory_csv import WriteTrajectoryCsv
from guidedarm.diagrams.tasks.joint_tour.scenario import JointTourScenario
from guidedarm.diagrams.tasks.registry import TaskDefinition
from guidedarm.systems.config_checks import CheckConfig, CheckInstance
from guidedarm.systems.errors import ConfigurationError


def MakeTourTrajectory(
    start: np.ndarray, waypoints: list[np.ndarray], max_speed: float
) -> PiecewisePolynomial:
    """Cubic segments with zero end velocities; a segment's duration is 1.5 x its largest
    joint move over max_speed, which bounds the cubic's peak speed by max_speed."""
    if not 0 < max_speed < np.inf:
        raise ConfigurationError(f"max_speed must be positive, got {max_speed}")
    if not waypoints:
        raise ConfigurationError("waypoints: at least one waypoint is needed")
    knots = [np.asarray(start, float)] + [np.asarray(w, float) for w in waypoints]
    times = [0.0]
    with np.errstate(over="ignore"):  # a tiny max_speed overflows to inf, refused below
        for a, b in itertools.pairwise(knots):
            times.append(times[-1] + max(1.5 * np.max(np.abs(b - a)) / max_speed, 1e-3))
    if not np.isfinite(times[-1]):
        raise ConfigurationError(f"max_speed {max_speed} rad/s is too small to time the tour")
    samples = np.column_stack(knots)
    zero = np.zeros_like(knots[0])
    return (
        PiecewisePolynomial.CubicWithContinuousSecondDerivatives(times, samples, zero, zero)
        if len(knots) > 2
        else PiecewisePolynomial.CubicHermite(times, samples, np.column_stack([zero, zero]))
    )


def TourStart(scenario: JointTourScenario) -> np.ndarray:
    """The arm's start (rad), after the scenario's checks (JointTourScenario.Validate) and
    refusing waypoints that do not fit the arm's model: a wrong number of joints, or
    positions outside its joint limits."""
    CheckInstance("scenario", scenario, JointTourScenario)
    CheckConfig(scenario)
    arms = scenario.station.arms
    plant = MakeMultibodyPlant(scenario.station, [scenario.arm])
    for i, w in enumerate(scenario.waypoints):
        CheckJointPositions(plant, scenario.arm, w, f"waypoints[{i}]")
    return ArmInitialPosition(plant, scenario.arm, arms[scenario.arm])


@dataclass(frozen=True)
class PreparedTour:
    """What a joint tour checks before it runs and then reuses: the arm's start (rad) and
    the tour from it through the waypoints."""

    start: np.ndarray
    trajectory: PiecewisePolynomial


def PrepareJointTour(scenario: JointTourScenario) -> PreparedTour:
    """The start (TourStart, refusing waypoints the arm's model cannot take) and the tour
    (MakeTourTrajectory) of `scenario`."""
    start = TourStart(scenario)
    return PreparedTour(start, MakeTourTrajectory(start, scenario.waypoints, scenario.max_speed))


def RunJointTour(
    scenario: JointTourScenario, context: RunContext, prepared: PreparedTour | None = None
) -> dict[str, Any]:
    """Simulates the tour (`prepared`, default PrepareJointTour(scenario)) and returns
    tracking metrics (rad)."""
    prepared = prepared or PrepareJointTour(scenario)
    start, trajectory = prepared.start, prepared.trajectory
    n = trajectory.rows()
    builder = DiagramBuilder()
    station = builder.AddNamedSystem(
        "station", MakeStation(scenario.station, context.meshcat, context.station_kind)
    )
    source = builder.AddNamedSystem("tour", TrajectorySource(trajectory))
    builder.Connect(
        source.get_output_port(), station.GetInputPort(f"{scenario.arm}.position_commanded")
    )
    AddJointTourOverlays(
        builder,
        context.meshcat,
        scenario.station,
        scenario.arm,
        source.get_output_port(),
        [start, *scenario.waypoints],
    )
    commanded = builder.AddNamedSystem("commanded_log", VectorLogSink(n))
    measured = builder.AddNamedSystem("measured_log", VectorLogSink(n))
    builder.Connect(source.get_output_port(), commanded.get_input_port())
    builder.Connect(
        station.GetOutputPort(f"{scenario.arm}.position_measured"), measured.get_input_port()
    )
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ApplySimulatorConfig(scenario.station.simulator_config, simulator)
    simulator.Initialize()
    if context.hardware:
        CheckArmAtStart(station, simulator.get_context(), scenario.arm, start)
    context.start_recording()
    t_end = AdvanceWithProgress(simulator, trajectory.end_time() + scenario.settle_time, context)
    context.write_replay()

    root = simulator.get_context()
    q_cmd = commanded.FindLog(root).data()
    q_meas = measured.FindLog(root).data()
    times = measured.FindLog(root).sample_times()
    context.save_figure(
        PlotJointSeries(times, {"commanded": q_cmd, "measured": q_meas}, "q (rad)"), "joints"
    )
    period = scenario.station.arms[scenario.arm].control_period
    grid = np.arange(0.0, times[-1] + period / 2, period)
    WriteTrajectoryCsv(
        context,
        grid,
        trajectory.vector_values(grid).T,
        _Derivative(trajectory, grid, 1),
        _Derivative(trajectory, grid, 2),
        np.column_stack([np.interp(grid, times, row) for row in q_meas]),
    )
    final_error = float(np.max(np.abs(trajectory.vector_values(times[-1:]) - q_meas[:, -1:])))
    delay, tracking_error = DelayedTrackingError(
        times, lambda t: trajectory.vector_values(t).T, q_meas.T, norm=np.inf
    )
    failure = None
    if not tracking_error <= scenario.max_tracking_error:
        failure = (
            f"the measured arm was {tracking_error:.4g} rad from the commanded tour "
            f"(max_tracking_error {scenario.max_tracking_error} rad)"
        )
    elif not final_error <= scenario.max_final_error:
        failure = (
            f"the measured arm ended {final_error:.4g} rad from the last waypoint "
            f"(max_final_error {scenario.max_final_error} rad)"
        )
    metrics = {
        "sim_time_s": round(t_end, 4),
        "tracking_error_max_rad": tracking_error,
        "tracking_delay_s": delay,
        "final_error_rad": final_error,
        "failure": failure,
    }
    q_true = TrueArmPositions(station, root, scenario.arm)
    if q_true is not None:
        last = trajectory.vector_values(times[-1:])[:, 0]
        metrics["true_final_error_rad"] = float(np.max(np.abs(last - q_true)))
    return metrics


def _Derivative(trajectory: PiecewisePolynomial, times: np.ndarray, order: int) -> np.ndarray:
    """The trajectory's derivative of `order` at times (samples x joints), 0 after its end
    (the tour holds its last waypoint)."""
    values = trajectory.MakeDerivative(order).vector_values(times).T
    values[times > trajectory.end_time()] = 0.0
    return values


# The numbers of RunJointTour's summary (TaskDefinition.metrics).
JOINT_TOUR_METRICS = {
    "sim_time_s": ("s", "simulated time of the run"),
    "tracking_error_max_rad": (
        "rad",
        "largest distance, on any joint, of the measured arm from the commanded tour, "
        "compared at tracking_delay_s",
    ),
    "tracking_delay_s": (
        "s",
        "the delay of the measured arm behind the commands that fits it best (0 to 0.1 s; "
        "0 in simulation)",
    ),
    "final_error_rad": ("rad", "largest joint distance of the measured arm from the last waypoint"),
    "true_final_error_rad": (
        "rad",
        "largest distance of the true arm's joints (the measured ones less the cell's joint "
        "offsets) from the last waypoint",
    ),
}

TASK = TaskDefinition(
    name="joint_tour",
    scenario_type=JointTourScenario,
    run=RunJointTour,
    description="move one arm through joint-space waypoints (station smoke test)",
    metrics=JOINT_TOUR_METRICS,
    prepare=PrepareJointTour,
)
