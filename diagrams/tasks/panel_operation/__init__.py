"""Task `panel_operation`: the rover arm presses a panel switch guided by its camera
(Annusewicz-Mistal et al.).

scenario (PanelOperationScenario) -> builder (AddPanelOperation: camera -> estimator ->
sequencer -> the arm) -> run (PanelOperationRun, TASK) -> report (metrics, figures)."""

from guidedarm.diagrams.tasks.panel_operation.builder import (
    AddPanelOperation,
    MakeCameraArmKinematics,
    PanelOperationSystems,
)
from guidedarm.diagrams.tasks.panel_operation.run import TASK, PanelOperationRun
from guidedarm.diagrams.tasks.panel_operation.scenario import (
    PanelOperationScenario,
    PanelPlannerConfig,
    StartConfig,
)

__all__ = [
    "TASK",
    "AddPanelOperation",
    "MakeCameraArmKinematics",
    "PanelOperationRun",
    "PanelOperationScenario",
    "PanelOperationSystems",
    "PanelPlannerConfig",
    "StartConfig",
]
