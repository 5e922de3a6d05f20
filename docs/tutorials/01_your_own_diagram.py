# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 1. Your own diagram: a station, the planner, a LeafSystem of yours, a replay
#
# guidedarm's station is an ordinary Drake `Diagram`: its ports have fixed names
# (`<arm>.position_commanded` in, `<arm>.state_estimated` out, ...), so you wire it like
# any Drake system. Here: the UR10e station, Pająk's acceleration-level planner through
# three waypoints, the planner's waypoint overlays, and a LeafSystem written in this
# notebook that measures the length of the path the tool travels. Meshcat records the run; the
# replay is saved as an offline page and shown below.

# %%
import html
import os
import tempfile

import numpy as np
from IPython.display import display
from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from guidedarm.diagrams.overlays.waypoint_overlays import AddWaypointOverlays
from guidedarm.diagrams.run_context import MakeMeshcat, SaveReplay, StartReplay
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station import MakeStation
from guidedarm.diagrams.station.station_plant import MakeMultibodyPlant
from guidedarm.diagrams.tasks.common.planner_builder import MakeAccelerationPlanner

os.chdir(tempfile.mkdtemp(prefix="guidedarm-tutorial-"))  # the files it writes go here

# %% [markdown]
# The station's scenario: Drake model directives (the models come from guidedarm's
# `models/` package) and the arm's initial joints. `yaml_load_typed` checks every key.

# %%
STATION = """
directives: [{add_directives: {file: package://guidedarm/directives/ur10e.dmd.yaml}}]
arms: {ur10e: {initial_position: [-1.5708, -1.5708, -2.356194, -0.785398, 1.5708, 0.785398]}}
"""
scenario = yaml_load_typed(schema=StationScenario, data=STATION)


# %% [markdown]
# A LeafSystem of your own, the Drake way: an input port, discrete state, an output port
# reading that state, a periodic update. Its maths is the plant's forward kinematics.


# %%
class ToolPathLength(LeafSystem):
    """Input `state` (the arm's [q; v], rad, rad/s); output `path_length` (1, m): the
    length of the path the origin of `tool_frame` has travelled, sampled every `period` s.
    Its state: [length, x, y, z of the last sample (NaN before the first)]."""

    def __init__(self, plant, tool_frame: str, period: float = 0.01) -> None:
        super().__init__()
        self._plant, self._context = plant, plant.CreateDefaultContext()
        self._frame = plant.GetFrameByName(tool_frame)
        self._state = self.DeclareVectorInputPort("state", plant.num_multibody_states())
        self._index = self.DeclareDiscreteState([0.0, np.nan, np.nan, np.nan])
        self.DeclareVectorOutputPort("path_length", 1, self.CalcLength)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self.Update)

    def Update(self, context, discrete_state) -> None:
        self._plant.SetPositionsAndVelocities(self._context, self._state.Eval(context))
        p = self._frame.CalcPoseInWorld(self._context).translation()
        length, *last = context.get_discrete_state(self._index).get_value()
        if not np.isnan(last[0]):
            length += np.linalg.norm(p - last)
        discrete_state.set_value(BasicVector([length, *p]).value())

    def CalcLength(self, context, output) -> None:
        output.SetAtIndex(0, context.get_discrete_state(self._index).GetAtIndex(0))


# %% [markdown]
# The diagram: station, planner (`MakeAccelerationPlanner` builds its own plant of the arm
# and refuses any waypoint inverse kinematics cannot reach, before anything moves), your
# system, and the overlays. Waypoints are rows [x, y, z, roll, pitch, yaw] of the TCP in
# the arm's base frame (m, rad).

# %%
waypoints = [
    [-0.175, -0.800, 0.730, np.pi, 0.0, 3 * np.pi / 4],
    [0.275, -0.800, 0.600, np.pi, 0.0, 3 * np.pi / 4],
    [0.275, -0.525, 0.730, np.pi, 0.0, 3 * np.pi / 4],
]
meshcat = MakeMeshcat()  # records only; MakeMeshcat(serve=True) serves a live page
builder = DiagramBuilder()
station = builder.AddSystem(MakeStation(scenario, meshcat))
planner = builder.AddSystem(
    MakeAccelerationPlanner(scenario, "ur10e", "ur10e::base", "ur10e::tool0", waypoints)
)
builder.Connect(station.GetOutputPort("ur10e.state_estimated"), planner.GetInputPort("arm_state"))
builder.Connect(
    planner.GetOutputPort("position_commanded"), station.GetInputPort("ur10e.position_commanded")
)
length = builder.AddSystem(ToolPathLength(MakeMultibodyPlant(scenario, ["ur10e"]), "tool0"))
builder.Connect(station.GetOutputPort("ur10e.state_estimated"), length.get_input_port())
AddWaypointOverlays(
    builder,
    meshcat,
    planner.planning,
    planner.GetOutputPort("position_commanded"),
    np.array(scenario.arms["ur10e"].initial_position),
)
diagram = builder.Build()

# %% [markdown]
# Simulate 5 s with the recording on, then save the replay.

# %%
simulator = Simulator(diagram)
StartReplay(meshcat)
simulator.AdvanceTo(5.0)
page = SaveReplay(meshcat, "my_diagram_replay.html")

context = simulator.get_context()
T = planner.GetOutputPort("planner_state").Eval(planner.GetMyContextFromRoot(context))[-1]
travelled = length.get_output_port().Eval(length.GetMyContextFromRoot(context))[0]
legs = np.linalg.norm(np.diff(np.array(waypoints)[:, :3], axis=0), axis=1).sum()
print(f"the planner ended its task at T = {T:.2f} s; the tool travelled {travelled:.3f} m")
print(f"(the straight legs between the waypoints: {legs:.3f} m, plus the way to the first)")
assert 0 < T < 5 and legs < travelled < 3 * legs

# %% [markdown]
# The replay, inline (a browser can also open `my_diagram_replay.html` on its own):
# drag to turn the view, and play the animation from the Meshcat controls.

# %%
iframe = f'<iframe srcdoc="{html.escape(page.read_text())}" width="100%" height="450"></iframe>'
display({"text/html": iframe}, raw=True)
