"""ToF path following on the UR10e in your own diagram: copy this file and adapt it.

The UR10e holds the six-sensor ToF tool of Wawrzyniak et al. ("Three-Dimensional
Path-Following with Articulated 6DoF Robot and ToF Sensors", 2025) and follows a 20 mm hose
0.62-0.68 m from its base, beyond the Nachi cell of the paper. The simulated station
(MakeStation) and the follower loop (AddPathFollowing: PathFollower + ToolPoseIk) are one
Drake Diagram, simulated until the follower stops at the end of the hose.

Run: .venv/bin/python examples/tof_following_on_ur10e.py [--estimator ranging]
"""

import argparse
import dataclasses

from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from guidedarm.diagrams.scenario_loading import SCENARIO_DIR
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.path_following import PathFollowingScenario
from guidedarm.diagrams.tasks.path_following.builder import AddPathFollowing
from guidedarm.diagrams.tasks.path_following.execution import LastRecordPerStep
from guidedarm.diagrams.tasks.path_following.report import Metrics
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--estimator", choices=["grid", "ranging"], default="grid")
args = parser.parse_args()

# The shipped scenario: the UR10e's model directives with the gripper and ToF tool on
# tool0, the hose (in ur10e::base), and the workspace walls widened for it.
scenario = yaml_load_typed(
    schema=PathFollowingScenario, filename=str(SCENARIO_DIR / "ur10e_path_following.yaml")
)
scenario = dataclasses.replace(scenario, estimator=args.estimator)
setup = MakeSetup(scenario)  # the hose, the walls, the IK, and the start pose on the hose

builder = DiagramBuilder()
station = builder.AddNamedSystem("station", MakeStation(setup.station))
follower, ik = AddPathFollowing(builder, station, setup)
steps = LogVectorOutput(follower.GetOutputPort("step_record"), builder, setup.period)
simulator = Simulator(builder.Build())
# The follower ends AdvanceTo when it stops (its update returns ReachedTermination).
simulator.AdvanceTo(scenario.max_time)

root = simulator.get_context()
failure = follower.GetOutputPort("failure").Eval(follower.GetMyContextFromRoot(root))
metrics = Metrics(LastRecordPerStep(steps.FindLog(root).data().T), setup.centerline)
print(f"estimator: {args.estimator}, steps: {metrics['steps']}, simulated {root.get_time():.1f} s")
print(f"coverage: {metrics['coverage']:.3f}")
print(
    f"tracking error mean / max: {metrics['tracking_error_mean_mm']:.2f} / "
    f"{metrics['tracking_error_max_mm']:.2f} mm"
)
print(
    f"detected-path error mean / max: {metrics['detected_path_error_mean_mm']:.2f} / "
    f"{metrics['detected_path_error_max_mm']:.2f} mm"
)
print(f"failure: {failure or 'none'}")
raise SystemExit(1 if failure or metrics["coverage"] < scenario.min_coverage else 0)
