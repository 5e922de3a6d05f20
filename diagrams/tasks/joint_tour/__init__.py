"""Task `joint_tour`: an arm through joint-space waypoints on cubic segments, with its
tracking measured.

scenario (JointTourScenario) -> run (TASK)."""

from guidedarm.diagrams.tasks.joint_tour.run import TASK
from guidedarm.diagrams.tasks.joint_tour.scenario import JointTourScenario

__all__ = ["TASK", "JointTourScenario"]
