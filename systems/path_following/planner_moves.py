"""Path-follower moves through the acceleration-level planner (Pająk).

Each segment of a move (joint waypoints, as the follower asks for them) becomes one planner
task: the tool frame's pose at the segment's end joints is the final location, and the
planner's law (joint velocity penalty, acceleration scaling) runs from rest at the
segment's start until the tool is within the planner's tolerances and then settle_time
more. The move ends where the planner ends (within position_tolerance of the IK solution's
tool pose), not at the IK joints themselves; the follower reads its sensors there. The
segment's end joints are also the target of the robust mode's joint-space blend near
singularities.
"""

import numpy as np

from guidedarm.systems.path_following.joint_moves import SampledMove
from guidedarm.systems.planning.acceleration_planner_math import (
    AccelerationPlanning,
    PlanningError,
    RunPlanning,
)


class PlannerMoves:
    """Plans follower moves with `planning` (its kinematics' tool frame is the follower's
    tool frame T); max_time (s) bounds one segment, settle_time (s) follows each."""

    def __init__(
        self, planning: AccelerationPlanning, max_time: float = 10.0, settle_time: float = 0.2
    ) -> None:
        self.planning = planning
        self.max_time = max_time
        self.settle_time = settle_time

    def __call__(self, waypoints: list[np.ndarray], tool_points: list[np.ndarray]) -> SampledMove:
        """The move through `waypoints` (rad); tool_points are not needed (the planner
        sets its own pace) and are accepted for the follower's common interface."""
        q = np.asarray(waypoints[0], float)
        times, samples = [np.zeros(1)], [q[np.newaxis]]
        for k, q_end in enumerate(waypoints[1:]):
            q_end = np.asarray(q_end, float)
            target = self.planning.kinematics.Position(q_end)
            planning = self.planning.WithWaypoints(target[np.newaxis], q_end[np.newaxis])
            segment = RunPlanning(planning, q, self.max_time, self.settle_time)
            if segment.done_time < 0:
                raise PlanningError(
                    f"segment {k + 1} did not reach its target within {self.max_time} s"
                )
            times.append(times[-1][-1] + segment.times[1:])
            samples.append(segment.q[1:])
            q = segment.q[-1]
        return SampledMove(np.concatenate(times), np.concatenate(samples))
