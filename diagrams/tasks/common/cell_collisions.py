"""The arm against its cell and itself: collision checks before motion, contacts during it.

The planner's law knows joint limits but not the cell: a start pose inside the table, a
waypoint whose joint solution puts the wrist through a fixture, or a law that swings the
arm into its own base would only show up as a measured arm that stops while its command goes
on. CellCollisions holds the station's plant with its SceneGraph (no hose: controllers do
not know where it is) and reports, for joint positions of one arm, the pairs of bodies in
penetration that involve the arm or what it carries (its tools): arm against cell, and
against itself (Drake already filters the pairs of bodies joined by a joint).

Units: rad, m, s.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import DiagramBuilder

from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.diagrams.station.station_plant import GetArmInstance, MakeMultibodyPlant
from guidedarm.systems.errors import ConfigurationError

# Penetrations shallower than this (m) are resting contact of touching parts, not collisions.
PENETRATION_TOLERANCE_M = 1e-4


class CellCollisions:
    """Collision queries of `arm` (a key of scenario.arms) and the models it carries
    (`carried`: model instance names, e.g. the controller plant's tools) in the station;
    contacts with the models of `touched` (e.g. the panel the task presses) do not count."""

    def __init__(
        self,
        scenario: StationScenario,
        arm: str,
        carried: Sequence[str] = (),
        touched: Sequence[str] = (),
    ) -> None:
        builder = DiagramBuilder()
        scene_graph = builder.AddSystem(SceneGraph())
        self.plant = builder.AddSystem(MakeMultibodyPlant(scenario, scene_graph=scene_graph))
        builder.Connect(
            self.plant.get_geometry_pose_output_port(),
            scene_graph.get_source_pose_port(self.plant.get_source_id()),
        )
        self._diagram = builder.Build()
        self._context = self._diagram.CreateDefaultContext()
        self._plant_context = self.plant.GetMyMutableContextFromRoot(self._context)
        self._query_port = scene_graph.get_query_output_port()
        self._scene_context = scene_graph.GetMyContextFromRoot(self._context)
        self.arm = GetArmInstance(self.plant, arm)
        self._moving = {self.arm} | self._Instances(carried)
        self._touched = self._Instances(touched)

    def _Instances(self, names: Sequence[str]) -> set[ModelInstanceIndex]:
        plant = self.plant
        return {plant.GetModelInstanceByName(n) for n in names if plant.HasModelInstanceNamed(n)}

    def Contacts(self, q: np.ndarray) -> list[tuple[str, str, float]]:
        """The body pairs (scoped names) in penetration deeper than PENETRATION_TOLERANCE_M
        with the arm at joint positions q (rad), at least one of them moving with the arm;
        with their depths (m), deepest first."""
        self.plant.SetPositions(self._plant_context, self.arm, np.asarray(q, float))
        query = self._query_port.Eval(self._scene_context)
        inspector = query.inspector()
        found = []
        for pair in query.ComputePointPairPenetration():
            if pair.depth <= PENETRATION_TOLERANCE_M:
                continue
            bodies = [
                self.plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
                for geometry in (pair.id_A, pair.id_B)
            ]
            instances = [body.model_instance() for body in bodies]
            if any(i in self._touched for i in instances):
                continue
            if any(i in self._moving for i in instances):
                names = [body.scoped_name().to_string() for body in bodies]
                found.append((names[0], names[1], pair.depth))
        return sorted(found, key=lambda contact: -contact[2])

    def Refuse(self, q: np.ndarray, what: str) -> None:
        """Raises ConfigurationError (one line naming the bodies and `what`, e.g. "start
        pose") if the arm at q collides."""
        contacts = self.Contacts(q)
        if contacts:
            a, b, depth = contacts[0]
            raise ConfigurationError(
                f"{what} collides: {a} and {b} overlap by {1e3 * depth:.1f} mm "
                f"({len(contacts)} body pair(s) in contact)"
            )

    def FirstContact(self, q: np.ndarray, every: int = 5) -> int | None:
        """The first of every `every`-th sample of joint positions q (samples x joints, rad)
        at which the arm touches the cell or itself; None if none does."""
        for k in range(0, len(q), every):
            if self.Contacts(q[k]):
                return k
        return None

    def CountContacts(self, q_samples: np.ndarray) -> int:
        """The number of contact episodes along sampled joint positions (samples x joints):
        runs of consecutive samples in which the arm touches the cell or itself."""
        episodes, touching = 0, False
        for q in q_samples:
            now = bool(self.Contacts(q))
            episodes += now and not touching
            touching = now
        return episodes


def ModelNames(plant: MultibodyPlant) -> list[str]:
    """The names of a plant's model instances (e.g. a controller plant's arm and tools)."""
    return [
        plant.GetModelInstanceName(ModelInstanceIndex(i))
        for i in range(plant.num_model_instances())
    ]
