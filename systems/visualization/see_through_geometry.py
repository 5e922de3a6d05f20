"""SeeThroughGeometry: makes geometry drawn by the MeshcatVisualizer translucent."""

from __future__ import annotations

from pydrake.geometry import Meshcat
from pydrake.systems.framework import Context, EventStatus, LeafSystem

from guidedarm.systems.visualization.frame_trail_overlay import OVERLAY_PERIOD


class SeeThroughGeometry(LeafSystem):
    """Sets the Meshcat `paths` (e.g. /drake/illustration/hose_3) to `opacity`, so that
    overlays inside them (the detected path inside the hose) can be seen. The visualizer
    draws its geometry at its first publish, so this acts at the first publish after it
    (one OVERLAY_PERIOD in), and again at each new run of the diagram."""

    def __init__(self, meshcat: Meshcat, paths: list[str], opacity: float = 0.35) -> None:
        super().__init__()
        self._meshcat, self._paths, self._opacity = meshcat, list(paths), opacity
        self._done = False
        self.DeclareInitializationPublishEvent(self._Start)
        self.DeclarePeriodicPublishEvent(OVERLAY_PERIOD, OVERLAY_PERIOD, self._Publish)

    def _Start(self, context: Context) -> EventStatus:
        self._done = False
        return EventStatus.DidNothing()

    def _Publish(self, context: Context) -> EventStatus:
        if self._done:
            return EventStatus.DidNothing()
        for path in self._paths:
            self._meshcat.SetProperty(path, "modulated_opacity", self._opacity)
        self._done = True
        return EventStatus.Succeeded()
