"""Task `marker_view`: one rendered view of the marker panel from a free camera, and the
estimator's errors against the exact truth.

scenario (MarkerViewScenario) -> run (TASK)."""

from guidedarm.diagrams.tasks.marker_view.run import TASK
from guidedarm.diagrams.tasks.marker_view.scenario import MarkerViewScenario

__all__ = ["TASK", "MarkerViewScenario"]
