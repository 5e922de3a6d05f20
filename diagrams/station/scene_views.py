"""Named scenes of the three arms and camera placements for looking at them."""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import ModelDirective

from guidedarm.diagrams.station.model_paths import MODELS_DIR

ARM_SCENES = {"mz04d": "mz04d_cell", "ur10e": "ur10e", "rover_arm": "rover_arm"}

# Eye and target (m, world) of a camera that frames each scene.
SCENE_VIEWPOINTS = {
    "mz04d_cell": ((1.9, -1.5, 1.2), (0.05, 0.0, 0.15)),
    "ur10e": ((1.25, -1.6, 1.0), (-0.1, -0.35, 0.45)),
    "rover_arm": ((1.7, -1.4, 1.1), (0.45, 0.0, 0.45)),
}


def SceneDirectives(name: str) -> list[ModelDirective]:
    """Directives of an arm (`mz04d`, `ur10e`, `rover_arm`) or a directive file name."""
    scene = ARM_SCENES.get(name, name)
    path = MODELS_DIR / "directives" / f"{scene}.dmd.yaml"
    if not path.is_file():
        from guidedarm.systems.errors import ConfigurationError

        choices = sorted(set(ARM_SCENES) | {p.name.split(".")[0] for p in path.parent.iterdir()})
        raise ConfigurationError(f"unknown arm or scene '{name}' (choose from {choices})")
    directive = ModelDirective()
    directive.add_directives = _AddDirectives(f"package://guidedarm/directives/{scene}.dmd.yaml")
    return [directive]


def _AddDirectives(uri: str):
    from pydrake.multibody.parsing import AddDirectives

    add = AddDirectives()
    add.file = uri
    return add


def LookAt(eye: tuple[float, ...], target: tuple[float, ...]) -> RigidTransform:
    """X_WC of a Drake camera (x right, y down, z forward) at `eye` looking at `target`."""
    eye_W, target_W = np.asarray(eye, float), np.asarray(target, float)
    z = target_W - eye_W
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), eye_W)
