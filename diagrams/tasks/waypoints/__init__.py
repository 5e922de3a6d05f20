"""Task `waypoints`: an arm's TCP through waypoints with the acceleration-level planner
(Pająk).

scenario (WaypointsScenario) -> setup (MakePlannerSetup: the planner, the cell checks) ->
run (TASK) -> report (the paper's Table 2 figures, plots)."""

from guidedarm.diagrams.tasks.waypoints.run import TASK
from guidedarm.diagrams.tasks.waypoints.scenario import WaypointsScenario
from guidedarm.diagrams.tasks.waypoints.setup import MakePlannerSetup, PlannerSetup

__all__ = ["TASK", "MakePlannerSetup", "PlannerSetup", "WaypointsScenario"]
