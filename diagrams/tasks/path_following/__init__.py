"""Task `path_following`: follow a hose with the six-sensor ToF tool (Wawrzyniak et al.).

scenario (PathFollowingScenario and the rules between its keys) -> setup (MakeSetup: the
hose, the IK, the start pose) -> builder (AddPathFollowing, MakePlannerMoves) -> execution
(the loop on either station) and replay -> report (metrics, figures) -> run (TASK)."""

from guidedarm.diagrams.tasks.path_following.builder import AddPathFollowing, MakePlannerMoves
from guidedarm.diagrams.tasks.path_following.run import TASK
from guidedarm.diagrams.tasks.path_following.scenario import PathFollowingScenario
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup, Setup

__all__ = [
    "TASK",
    "AddPathFollowing",
    "MakePlannerMoves",
    "MakeSetup",
    "PathFollowingScenario",
    "Setup",
]
