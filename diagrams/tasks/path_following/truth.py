"""What the true cell did during a path-following run: where the true tool centre O was at
each step and in which steps the true robot touched the hose.

The follower's records hold the tool pose it believes (its measured joints through the
nominal kinematics). The simulated station's plant is the true cell (station.errors: joint
offsets, link errors, compliance); its state, logged from the `sim.plant_state` port,
gives the twins measured on it. A hardware station has no such port and no truth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import QueryObject
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, OutputPort
from pydrake.systems.primitives import LogVectorOutput, VectorLogSink

from guidedarm.systems.plant_frames import GetScopedFrame


@dataclass
class TrueCell:
    """The true tool centres O (steps x 3, m, world frame; at the step records' times) and
    the number of steps during which the true robot penetrated the hose."""

    p_WO: np.ndarray
    collisions: int


def AddTrueStateLog(
    builder: DiagramBuilder, station: Diagram, period: float
) -> VectorLogSink | None:
    """Logs the station's true plant state [q; v] every `period` (s); None for a station
    without truth (hardware)."""
    if not station.HasOutputPort("sim.plant_state"):
        return None
    return LogVectorOutput(station.GetOutputPort("sim.plant_state"), builder, period)


def MeasureTrueCell(
    station: Diagram,
    root: Context,
    log: VectorLogSink,
    tool_frame: str,
    step_times: np.ndarray,
    sample_times: np.ndarray,
) -> TrueCell:
    """The true tool centre O (the scoped `tool_frame`'s origin) at `step_times` and the
    contact steps at `sample_times` (s), from the true states in `log`, interpolated
    linearly between its samples, posed on a copy of the station's context `root`."""
    found = log.FindLog(root)
    times, states = found.sample_times(), found.data()
    posed = root.Clone()
    plant = station.GetSubsystemByName("plant")
    plant_context = plant.GetMyMutableContextFromRoot(posed)
    tool = GetScopedFrame(plant, tool_frame, "tool_frame")
    n = plant.num_positions()

    def Pose(t: float) -> None:
        q = [np.interp(t, times, row) for row in states[:n]]
        plant.SetPositions(plant_context, np.array(q))

    p_WO = np.zeros((len(step_times), 3))
    for i, t in enumerate(step_times):
        Pose(t)
        p_WO[i] = tool.CalcPoseInWorld(plant_context).translation()
    query_port = station.GetOutputPort("sim.query_object")
    query_context = station.GetMyContextFromRoot(posed)
    collisions = ContactSteps(
        query_port, query_context, Pose, sample_times, list(sample_times), step_times
    )
    return TrueCell(p_WO, collisions)


def ContactSteps(
    query_port: OutputPort,
    context: Context,
    pose: Callable[[object], None],
    sample_times: np.ndarray,
    samples: list,
    step_times: np.ndarray,
) -> int:
    """Steps during which some robot geometry penetrated the hose: `pose(sample)` poses the
    robot for each of `samples` (taken at `sample_times`, s) in `context`, whose
    `query_port` then answers; a sample belongs to the last step that started before
    it."""
    hit_steps = set()
    for t, sample in zip(sample_times, samples, strict=True):
        pose(sample)
        if _TouchesHose(query_port.Eval(context)):
            hit_steps.add(int(np.searchsorted(step_times, t, side="right")))
    return len(hit_steps)


def _TouchesHose(query: QueryObject) -> bool:
    inspector = query.inspector()
    for pair in query.ComputePointPairPenetration():
        names = (inspector.GetName(pair.id_A), inspector.GetName(pair.id_B))
        if any("hose_" in n and "bracket" not in n for n in names):
            return True
    return False
