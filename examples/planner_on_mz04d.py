"""The acceleration-level planner (Pająk, "New Approach to Planning the Complex Movements of
6-DOF Industrial Robot Subjected to Acceleration Constraints") in your own diagram, on the
Nachi MZ04D of the ToF path-following cell.

MakeAccelerationPlanner builds the planner's own plant from the station scenario (the arm,
its gripper and ToF tool), checks every waypoint by inverse kinematics before any motion and
returns a LeafSystem to wire between the station's state and command ports. Waypoints are
rows [x, y, z, roll, pitch, yaw] of the TCP (here the ToF tool's centre) in the arm's base
frame (m, rad). The run is recorded as a replay page a browser opens offline (StartReplay,
SaveReplay), with the planner's waypoints drawn in it (AddWaypointOverlays).
Run: .venv/bin/python examples/planner_on_mz04d.py [REPLAY.html]
"""

import sys

import numpy as np
from pydrake.multibody.parsing import AddDirectives, ModelDirective
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.overlays.waypoint_overlays import AddWaypointOverlays
from guidedarm.diagrams.run_context import MakeMeshcat, SaveReplay, StartReplay
from guidedarm.diagrams.station.scenario import ArmConfig, StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.tasks.common.planner_builder import MakeAccelerationPlanner
from guidedarm.systems.planning.acceleration_planner_state import PlannerState

scenario = StationScenario(
    directives=[
        ModelDirective(
            add_directives=AddDirectives(file="package://guidedarm/directives/mz04d_cell.dmd.yaml")
        )
    ],
    arms={"mz04d": ArmConfig(initial_position=[0.0, np.pi / 2, 0.0, 0.0, -np.pi / 2, 0.0])},
)
waypoints = [
    [0.35, 0.12, 0.22, 0.0, 0.0, np.pi / 4],
    [0.35, -0.12, 0.22, 0.0, 0.0, 1.0],
    [0.25, -0.05, 0.30, 0.0, 0.0, np.pi / 4],
]

meshcat = MakeMeshcat()  # records the replay; MakeMeshcat(serve=True) serves a live page
builder = DiagramBuilder()
station = builder.AddSystem(MakeStation(scenario, meshcat))
planner = builder.AddSystem(
    MakeAccelerationPlanner(scenario, "mz04d", "mz04d::base", "tof_tool::tof_tool", waypoints)
)
builder.Connect(station.GetOutputPort("mz04d.state_estimated"), planner.GetInputPort("arm_state"))
builder.Connect(
    planner.GetOutputPort("position_commanded"), station.GetInputPort("mz04d.position_commanded")
)
q_start = np.array(scenario.arms["mz04d"].initial_position)
AddWaypointOverlays(
    builder, meshcat, planner.planning, planner.GetOutputPort("position_commanded"), q_start
)
simulator = Simulator(builder.Build())
StartReplay(meshcat)
simulator.AdvanceTo(5.0)
page = SaveReplay(meshcat, sys.argv[1] if len(sys.argv) > 1 else "replay.html")

context = simulator.get_context()
q = station.GetOutputPort("mz04d.position_measured").Eval(station.GetMyContextFromRoot(context))
tcp = planner.planning.kinematics.Position(q)
state = planner.GetOutputPort("planner_state").Eval(planner.GetMyContextFromRoot(context))
T = state[PlannerState.DONE_ROW]
print(f"planner task ended at T = {T:.2f} s")
print(f"final TCP error (measured arm): {1e3 * np.linalg.norm(tcp[:3] - waypoints[-1][:3]):.3f} mm")
print(f"replay written to {page}")
