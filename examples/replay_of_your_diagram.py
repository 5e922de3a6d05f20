"""Your own diagram with a LeafSystem of your own, recorded as an offline replay page.

The UR10e station, Pająk's acceleration-level planner through three waypoints, the
planner's waypoint overlays, and `TcpSpeedMonitor`, a LeafSystem written here: it reads the
arm's measured joints and velocities and keeps the largest TCP speed as its state.
StartReplay / SaveReplay record everything drawn in Meshcat and write it as a page a
browser opens offline. Run: .venv/bin/python examples/replay_of_your_diagram.py [OUT.html]
"""

import sys

import numpy as np
from pydrake.common.yaml import yaml_load_typed
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from guidedarm.diagrams.overlays.waypoint_overlays import AddWaypointOverlays
from guidedarm.diagrams.run_context import MakeMeshcat, SaveReplay, StartReplay
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
from guidedarm.diagrams.tasks.planner_builder import MakeAccelerationPlanner


class TcpSpeedMonitor(LeafSystem):
    """Input `state` (the arm's [q; v], rad and rad/s); output `max_tcp_speed` (1, m/s):
    the largest speed of the frame `tcp_frame`'s origin seen so far, kept as discrete state
    updated every `period` s."""

    def __init__(self, plant: MultibodyPlant, tcp_frame: str, period: float = 0.01) -> None:
        super().__init__()
        self._plant = plant
        self._context = plant.CreateDefaultContext()
        self._frame = plant.GetFrameByName(tcp_frame)
        self._state = self.DeclareVectorInputPort("state", 2 * plant.num_positions())
        index = self.DeclareDiscreteState(1)
        self.DeclareStateOutputPort("max_tcp_speed", index)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self.UpdateMax)

    def UpdateMax(self, context, discrete_state) -> None:
        x = self._state.Eval(context)
        self._plant.SetPositionsAndVelocities(self._context, x)
        J = self._plant.CalcJacobianTranslationalVelocity(
            self._context,
            JacobianWrtVariable.kV,
            self._frame,
            np.zeros(3),
            self._plant.world_frame(),
            self._plant.world_frame(),
        )
        speed = float(np.linalg.norm(J @ x[self._plant.num_positions() :]))
        previous = discrete_state.get_vector().GetAtIndex(0)
        discrete_state.set_value(BasicVector([max(previous, speed)]).value())


STATION = """
directives: [{add_directives: {file: package://guidedarm/directives/ur10e.dmd.yaml}}]
arms: {ur10e: {initial_position: [-1.5708, -1.5708, -2.356194, -0.785398, 1.5708, 0.785398]}}
"""
scenario = yaml_load_typed(schema=StationScenario, data=STATION)
waypoints = [  # TCP rows [x, y, z, roll, pitch, yaw] in the arm's base frame (m, rad)
    [-0.175, -0.800, 0.730, np.pi, 0.0, 3 * np.pi / 4],
    [0.275, -0.800, 0.730, np.pi, 0.0, 3 * np.pi / 4],
    [0.275, -0.525, 0.730, np.pi, 0.0, 3 * np.pi / 4],
]

meshcat = MakeMeshcat()  # records only: no page is served
builder = DiagramBuilder()
station = builder.AddSystem(MakeStation(scenario, meshcat))
planner = builder.AddSystem(
    MakeAccelerationPlanner(scenario, "ur10e", "ur10e::base", "ur10e::tool0", waypoints)
)
builder.Connect(station.GetOutputPort("ur10e.state_estimated"), planner.GetInputPort("arm_state"))
builder.Connect(
    planner.GetOutputPort("position_commanded"), station.GetInputPort("ur10e.position_commanded")
)
monitor = builder.AddSystem(TcpSpeedMonitor(MakeMultibodyPlant(scenario, ["ur10e"]), "tool0"))
builder.Connect(station.GetOutputPort("ur10e.state_estimated"), monitor.get_input_port())
AddWaypointOverlays(
    builder,
    meshcat,
    planner.planning,
    planner.GetOutputPort("position_commanded"),
    np.array(scenario.arms["ur10e"].initial_position),
)

simulator = Simulator(builder.Build())
StartReplay(meshcat)
simulator.AdvanceTo(5.0)
page = SaveReplay(meshcat, sys.argv[1] if len(sys.argv) > 1 else "replay.html")

context = simulator.get_context()
speed = monitor.get_output_port().Eval(monitor.GetMyContextFromRoot(context))[0]
T = planner.GetOutputPort("planner_state").Eval(planner.GetMyContextFromRoot(context))[-1]
print(f"planner task ended at T = {T:.2f} s; largest TCP speed {speed:.3f} m/s")
print(f"replay written to {page} ({page.stat().st_size // 1024} KiB)")
