"""Wiring that every station branch shares: the ToF tools reading the scene's SceneGraph,
the arms' joint calibration and the Meshcat drawing of the plant. MakeStation (simulated),
MakeKinematicStation and MakeHardwareStation build them here, so all export the same ports.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Meshcat, SceneGraph
from pydrake.lcm import DrakeLcm
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder, System
from pydrake.systems.primitives import AffineSystem
from pydrake.visualization import ApplyVisualizationConfig

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.tof.tof_errors import ToFErrors
from guidedarm.systems.tof.tof_tool_sensor import TOF_PORTS, ToFToolSensor


def AddToFTools(
    builder: DiagramBuilder,
    scenario: StationScenario,
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
    errors: dict[str, ToFErrors] | None = None,
) -> None:
    """A ToFToolSensor per tool of scenario.tof_tools ("<name>.sensor", its target radius
    resolved and its calibration_file's offsets applied) on `scene_graph`'s query output,
    exporting `<name>.<port>` for every TOF_PORTS port. errors: the drawn ToFErrors by
    tool name (None or a missing tool: an exact tool)."""
    for name in scenario.tof_tools:
        sensor = builder.AddNamedSystem(
            f"{name}.sensor",
            ToFToolSensor(
                plant,
                scenario.ToFTool(name),
                (errors or {}).get(name),
                scenario.ToFCalibration(name),
            ),
        )
        builder.Connect(scene_graph.get_query_output_port(), sensor.get_input_port())
        for port in TOF_PORTS:
            builder.ExportOutput(sensor.GetOutputPort(port), f"{name}.{port}")


def AddOffset(builder: DiagramBuilder, name: str, offset: np.ndarray) -> System:
    """A feedthrough system named `name`: its output is its input plus `offset` (a vector)."""
    m = offset.size
    return builder.AddNamedSystem(
        name,
        AffineSystem(
            np.zeros((0, 0)), np.zeros((0, m)), np.zeros(0), np.zeros((m, 0)), np.eye(m), offset
        ),
    )


def AddMeshcatVisualization(
    builder: DiagramBuilder,
    scenario: StationScenario,
    meshcat: Meshcat | None,
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
) -> None:
    """Draws `scene_graph` (of the builder) with `plant`'s geometry in `meshcat` as
    scenario.visualization says (nothing without a Meshcat; StationScenario.Validate
    refuses an LCM bus)."""
    if meshcat is not None:
        # Meshcat only: on a null LCM bus ApplyVisualizationConfig adds no DrakeVisualizer,
        # whose LCM messages (for Meldis, which nothing here runs) cost 0.03 CPU s per
        # simulated second of path following.
        ApplyVisualizationConfig(
            scenario.visualization,
            builder,
            plant=plant,
            scene_graph=scene_graph,
            meshcat=meshcat,
            lcm=DrakeLcm("memq://null"),
        )
