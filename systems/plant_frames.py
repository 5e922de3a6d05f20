"""Frames of a MultibodyPlant named in scenarios as `instance::name` (or `name`)."""

from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame

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
