"""Running the path follower: the loop of builder.AddPathFollowing on one of
two stations.

station     MakeStation's: the plant, the computed-torque servos at 2 ms steps and the ToF
            tool (or, with --hardware, the drivers).
kinematic   MakeStation(..., kind="kinematic"): the same plant and ToF sensor on a
            SceneGraph, but the arm is wherever it is commanded (no dynamics, no 2 ms
            steps). The follower,
            its moves, retraces and recoveries, and the IK are the same systems; only the
            servo's tracking lag is missing. About 5 times faster; used for the random-path
            suite, where the physics of a 15 mm move at 50 mm/s adds nothing to what the
            follower sees.
Both return the per-step records (RECORD_FIELDS) and joint samples every 20 ms, which a
kinematic station of the same scene checks for robot-hose contact, and what the true cell
did (truth.TrueCell): the simulated station's from its plant's state; the kinematic
station's is the nominal cell posed exactly where commanded (station.errors are refused
with it), so its truth is its records; a hardware station has none.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from guidedarm.diagrams.run_context import AdvanceWithProgress, RunContext
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.task_run import InterruptedFailure
from guidedarm.diagrams.tasks.common.start_pose import CheckArmAtStart
from guidedarm.diagrams.tasks.path_following.builder import AddPathFollowing
from guidedarm.diagrams.tasks.path_following.replay import (
    AddReplayLogs,
    AddSetupOverlays,
    DrawReplay,
)
from guidedarm.diagrams.tasks.path_following.report import Positions
from guidedarm.diagrams.tasks.path_following.setup import Setup
from guidedarm.diagrams.tasks.path_following.truth import (
    AddTrueStateLog,
    ContactSteps,
    MeasureTrueCell,
    TrueCell,
)
from guidedarm.systems.errors import RunFailedError
from guidedarm.systems.path_following.continuous_follower import ContinuousFollower
from guidedarm.systems.path_following.path_follower import PathFollower

# Joint samples for the contact check (s): the tool moves 1 mm between two at 50 mm/s.
SAMPLE_PERIOD = 0.02


@dataclass
class Execution:
    """What a run produced: step records (steps x RECORD_FIELDS), joint samples (times,
    q rows) for the contact check, the simulated time (s), a failure line or None, and the
    number of steps during which the robot touched the hose, the wall-clock time (s) the
    simulation took (the follower's loop on its station, without setup and report), and
    whether a RunFailedError (e.g. a hardware fault), Ctrl-C or SIGTERM cut the simulation
    short; `truth`, what the true cell did (None without truth: hardware)."""

    records: np.ndarray
    sample_times: np.ndarray
    q_samples: np.ndarray
    sim_time: float
    failure: str | None
    collisions: int = 0
    wall_time: float = 0.0
    aborted: bool = False
    truth: TrueCell | None = None


def Execute(setup: Setup, executor: str, context: RunContext) -> Execution:
    """Runs the follower on the `station` or `kinematic` station until it stops or
    setup.max_time, then counts the steps with robot-hose contact."""
    kinematic = MakeStation(setup.station, kind="kinematic")
    drawing = _Drawing(executor, context)
    if executor == "kinematic":
        station = kinematic
    else:
        meshcat = context.meshcat if drawing == "loop" else None
        station = MakeStation(setup.station, meshcat, context.station_kind)
    builder = DiagramBuilder()
    builder.AddNamedSystem("station", station)
    follower, _ = AddPathFollowing(builder, station, setup)
    execution = _Simulate(setup, builder, station, follower, context, drawing)
    execution.collisions = CountContactSteps(execution, kinematic, setup.arm)
    if executor == "kinematic":
        execution.truth = TrueCell(Positions(execution.records, "O"), execution.collisions)
    return execution


def _Simulate(
    setup: Setup,
    builder: DiagramBuilder,
    station: Diagram,
    follower: PathFollower | ContinuousFollower,
    context: RunContext,
    drawing: str,
) -> Execution:
    """Adds the logs and drawing to the loop in `builder`, runs it and collects what it
    recorded."""
    drawn_in_loop = drawing == "loop"
    replay_logs = (
        AddReplayLogs(builder, station, follower, setup.arm) if drawing == "after" else None
    )
    AddSetupOverlays(builder, context.meshcat if drawn_in_loop else None, station, follower, setup)
    record_period = setup.continuous.servo_period if setup.motion == "continuous" else setup.period
    record_log = LogVectorOutput(follower.GetOutputPort("step_record"), builder, record_period)
    q_log = LogVectorOutput(
        station.GetOutputPort(f"{setup.arm}.position_measured"), builder, SAMPLE_PERIOD
    )
    true_log = AddTrueStateLog(builder, station, record_period)
    simulator = Simulator(builder.Build())
    ApplySimulatorConfig(setup.station.simulator_config, simulator)
    root = simulator.get_mutable_context()
    follower_context = follower.GetMyContextFromRoot(root)
    simulator.Initialize()
    if context.hardware:
        CheckArmAtStart(station, root, setup.arm, setup.q_start)
    if drawn_in_loop:
        context.start_recording()
    start = time.perf_counter()
    fault = None
    try:
        # The follower's update ends AdvanceTo once it stops (ReachedTermination).
        AdvanceWithProgress(
            simulator,
            setup.max_time,
            context,
            describe=lambda: (
                f"step {follower.Loop(follower_context).step}, t = {root.get_time():.1f} s"
            ),
        )
    except (RunFailedError, KeyboardInterrupt) as e:
        # a device fault, Ctrl-C or SIGTERM: the summary keeps what was measured so far
        fault = InterruptedFailure(e) if isinstance(e, KeyboardInterrupt) else str(e)
        context.progress(f"{fault}; writing the summary", force=True)
    wall_time = time.perf_counter() - start
    if drawn_in_loop:
        context.write_replay()
    elif replay_logs is not None:
        DrawReplay(replay_logs, root, setup, context)
    loop = follower.Loop(follower_context)
    failure = fault or loop.failure or None
    if failure is None and not follower.Stopped(follower_context):
        failure = f"time limit ({setup.max_time} s) reached at step {loop.step}"
    records = LastRecordPerStep(record_log.FindLog(root).data().T)
    samples = q_log.FindLog(root)
    truth = None
    if true_log is not None:
        tool_frame = setup.station.tof_tools[setup.tool_name].tool_frame
        step_times = records[:, 1] if len(records) else np.zeros(0)
        truth = MeasureTrueCell(
            station, root, true_log, tool_frame, step_times, samples.sample_times()
        )
    return Execution(
        records,
        samples.sample_times(),
        samples.data().T,
        root.get_time(),
        failure,
        wall_time=wall_time,
        aborted=fault is not None,
        truth=truth,
    )


def _Drawing(executor: str, context: RunContext) -> str:
    """How the run is drawn in Meshcat: `none` (the kinematic executor, or no Meshcat),
    `after` the loop from its logs (path_following_replay) when Meshcat only records the
    simulated station's replay and nobody watches the loop, else in the `loop` (a live
    page; a hardware run, whose station draws the arm from the drivers' measurements)."""
    if executor == "kinematic" or context.meshcat is None:
        return "none"
    return "loop" if context.live or context.hardware else "after"


def LastRecordPerStep(samples: np.ndarray) -> np.ndarray:
    """The last logged `step_record` of each step (rows of RECORD_FIELDS), from the samples
    of a logger of that port: a step's IK time arrives after its reading."""
    steps = samples[:, 0]
    keep = [
        i
        for i in range(len(samples))
        if steps[i] >= 0 and (i + 1 == len(samples) or steps[i + 1] != steps[i])
    ]
    return samples[keep]


def CountContactSteps(execution: Execution, kinematic_station: Diagram, arm: str) -> int:
    """Steps during which some robot geometry penetrated the hose (at the joint samples),
    posed on a kinematic station of the scene (the nominal cell at the measured joints)."""
    context = kinematic_station.CreateDefaultContext()
    command = kinematic_station.GetInputPort(f"{arm}.position_commanded")
    step_times = execution.records[:, 1] if len(execution.records) else np.zeros(0)
    return ContactSteps(
        kinematic_station.GetOutputPort("sim.query_object"),
        context,
        lambda q: command.FixValue(context, q),
        execution.sample_times,
        list(execution.q_samples),
        step_times,
    )
