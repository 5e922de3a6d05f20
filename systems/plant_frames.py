"""Frames of a MultibodyPlant named in scenarios as `instance::name` (or `name`), and the
checks of the plant and frame arguments of public builders."""

from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex

from guidedarm.systems.config_checks import CheckInstance, FieldError
from guidedarm.systems.errors import ConfigurationError


def GetScopedFrame(plant: MultibodyPlant, scoped_name: str, key: str) -> Frame:
    """The frame `instance::name` (or `name`) of plant; ConfigurationError naming `key`."""
    instance_name, sep, frame_name = scoped_name.rpartition("::")
    try:
        if not sep:
            return plant.GetFrameByName(frame_name)
        return plant.GetFrameByName(frame_name, plant.GetModelInstanceByName(instance_name))
    except Exception:
        raise ConfigurationError(f"{key}: no frame '{scoped_name}' in the station") from None


def CheckPlant(name: str, plant: object, scene_graph: bool = False) -> None:
    """Checks a plant argument: a finalized MultibodyPlant, registered as a geometry source
    with a SceneGraph if `scene_graph` (geometry queries need that); FieldError naming
    `name` otherwise."""
    CheckInstance(name, plant, MultibodyPlant)
    if not plant.is_finalized():
        raise FieldError(
            name, "the plant must be finalized (plant.Finalize(), or use MakeMultibodyPlant)"
        )
    if scene_graph and not plant.geometry_source_is_registered():
        raise FieldError(
            name,
            "the plant must be registered with a SceneGraph "
            "(e.g. MakeMultibodyPlant(..., scene_graph=scene_graph), or the station's plant)",
        )


def CheckFrame(name: str, frame: object, plant: MultibodyPlant) -> None:
    """Checks a frame argument: a Frame of `plant` (not of another plant); FieldError naming
    `name` otherwise."""
    CheckInstance(name, frame, Frame)
    if frame.GetParentPlant() is not plant:
        raise FieldError(name, f"frame '{frame.name()}' belongs to another plant")


def CheckModelInstance(name: str, instance: object, plant: MultibodyPlant) -> None:
    """Checks a model instance argument: a ModelInstanceIndex of `plant`; FieldError naming
    `name` otherwise."""
    CheckInstance(name, instance, ModelInstanceIndex)
    if not int(instance) < plant.num_model_instances():
        raise FieldError(name, f"no model instance {int(instance)} in the plant")
