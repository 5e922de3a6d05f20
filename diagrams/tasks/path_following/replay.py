"""The replay of a path-following run, drawn after its loop.

Without a live page (no `--meshcat`), Meshcat only records replay.html; drawing it during
the loop (the station's MeshcatVisualizer and the overlays, in Python) would slow the loop
for nobody to see. Instead the loop logs what the drawing reads, at the drawing's period
(AddReplayLogs: the arm's measured joints and the follower's `step_record`, `detections`
and `detection_errors`), and DrawReplay plays the logs back through the same overlays on a
kinematic station of the same scene, with the same MeshcatVisualizer, at the same times:
the same replay.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, LeafSystem, System
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial

from guidedarm.diagrams.overlays.path_following_overlays import AddPathFollowingOverlays
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.station.kinematic_station import MakeKinematicStation
from guidedarm.diagrams.tasks.path_following.setup import Setup
from guidedarm.systems.visualization.frame_trail_overlay import OVERLAY_PERIOD

# The follower's outputs the overlays draw.
FOLLOWER_PORTS = ("step_record", "detections", "detection_errors")


@dataclass
class ReplayLogs:
    """Loggers, every OVERLAY_PERIOD, of the arm's measured joints and of FOLLOWER_PORTS."""

    q: VectorLogSink
    follower: dict[str, VectorLogSink]


def AddReplayLogs(
    builder: DiagramBuilder, station: Diagram, follower: LeafSystem, arm: str
) -> ReplayLogs:
    """Logs what AddPathFollowingOverlays would read, when it would read it."""
    q = LogVectorOutput(station.GetOutputPort(f"{arm}.position_measured"), builder, OVERLAY_PERIOD)
    logs = {
        name: LogVectorOutput(follower.GetOutputPort(name), builder, OVERLAY_PERIOD)
        for name in FOLLOWER_PORTS
    }
    return ReplayLogs(q, logs)


def AddSetupOverlays(
    builder: DiagramBuilder,
    meshcat: Meshcat | None,
    station: Diagram,
    follower: System,
    setup: Setup,
) -> None:
    """AddPathFollowingOverlays for the run `setup` describes (its arm, ToF tool and IK
    plant); nothing without a Meshcat."""
    AddPathFollowingOverlays(
        builder,
        meshcat,
        station,
        follower,
        setup.solver.plant,
        setup.station,
        setup.arm,
        setup.tool_name,
    )


def DrawReplay(logs: ReplayLogs, root: Context, setup: Setup, context: RunContext) -> None:
    """Records the run's drawing from `logs` (in the loop's root context) into
    context.meshcat, up to the loop's final time, and writes replay.html."""
    builder = DiagramBuilder()
    # The drawing needs the scene, not the sensor: no ToF tool (its rays cost time), and
    # so none of the tool's errors either.
    no_tool_errors = replace(setup.station.errors, tof_tools={})
    scene = replace(setup.station, tof_tools={}, errors=no_tool_errors)
    station = builder.AddNamedSystem("station", MakeKinematicStation(scene, context.meshcat))
    joints = builder.AddNamedSystem("logged_joints", _Playback(logs.q, root))
    builder.Connect(
        joints.get_output_port(), station.GetInputPort(f"{setup.arm}.position_commanded")
    )
    follower = builder.AddNamedSystem("logged_follower", _LoggedFollower(logs, root))
    AddSetupOverlays(builder, context.meshcat, station, follower, setup)
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    context.start_recording()
    simulator.AdvanceTo(root.get_time())
    context.write_replay()


def _Playback(log: VectorLogSink, root: Context) -> TrajectorySource:
    """The logged samples as a signal: each holds from half a period before its time to
    half a period before the next, so a publish at a sample's time reads that sample
    whatever the rounding of either time. The last sample is repeated a period later: a
    zero-order hold's last breakpoint only ends the segment of the sample before it."""
    samples = log.FindLog(root)
    times = np.r_[samples.sample_times(), samples.sample_times()[-1] + OVERLAY_PERIOD]
    values = np.hstack([samples.data(), samples.data()[:, -1:]])
    return TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times - OVERLAY_PERIOD / 2, values))


def _LoggedFollower(logs: ReplayLogs, root: Context) -> Diagram:
    """A Diagram whose outputs FOLLOWER_PORTS play back the follower's logged outputs."""
    builder = DiagramBuilder()
    for name, log in logs.follower.items():
        source = builder.AddNamedSystem(name, _Playback(log, root))
        builder.ExportOutput(source.get_output_port(), name)
    return builder.Build()
