"""`station.errors`: what the real cell has and its controllers do not know.

The simulated station (MakeStation) builds the true cell from the scenario's models plus
these errors; controllers, IK, planners and estimators keep the nominal models (the
directives, URDFs and camera files). Every value is a number or a Drake distribution
(systems/cell_errors/distributions.py), drawn once per run from the scenario's
random_seed, one stream per source. A scenario may name presets,
`station.errors_preset: NAME[,NAME...]` (models/errors/NAME.yaml, each a StationErrors
mapping); entries of `station.errors` override theirs, field by field.
"""

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydrake.common.schema import Transform
from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from guidedarm.systems.cell_errors.camera_errors import CameraErrors
from guidedarm.systems.cell_errors.distributions import (
    DrawErrors,
    ErrorsAsData,
    IsZeroError,
    ScalarError,
    VectorError,
)
from guidedarm.systems.config_checks import CheckFields
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.tof.tof_errors import ToFErrors

PRESET_DIR = Path(__file__).resolve().parents[2] / "models" / "errors"


@dataclass
class ArmErrors:
    """The errors of one arm (station.errors.arms.<arm>).

    joint_offset: per joint, the true joint angle minus the measured one (rad); empty: 0.
    encoder_resolution: the encoders' step (rad); 0: exact.
    joint_stiffness: per joint, the transmission's stiffness (N m/rad); empty: rigid. The
        link deflects from the motor angle under the gravity torque it holds while the
        encoder reads the motor side (systems/cell_errors/joint_encoder.py).
    link_errors: per revolute joint, the true pose of its frame on its parent link in
        the nominal one (the links' length and twist errors; m, rad); empty: none.
    base_stiffness: [k_x, k_y], the stiffness of a tilt of the arm's base about the x
        and y axes of the weld that holds it (N m/rad; a rover's suspension), each a
        revolute joint with a spring; empty: the base is welded (rigid).
    base_damping: [c_x, c_y], the damping of those tilts (N m s/rad).
    """

    joint_offset: VectorError = field(default_factory=list)
    encoder_resolution: ScalarError = 0.0
    joint_stiffness: VectorError = field(default_factory=list)
    link_errors: list[Transform] = field(default_factory=list)
    base_stiffness: VectorError = field(default_factory=list)
    base_damping: VectorError = field(default_factory=list)

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field (drawn values only)."""
        CheckFields(self)
        if isinstance(self.encoder_resolution, float | int) and not self.encoder_resolution >= 0:
            raise ConfigurationError(
                f"encoder_resolution must be >= 0, got {self.encoder_resolution}"
            )
        if isinstance(self.joint_stiffness, list) and not all(k > 0 for k in self.joint_stiffness):
            raise ConfigurationError("joint_stiffness: every stiffness must be > 0 (N m/rad)")
        for name in ("base_stiffness", "base_damping"):
            values = getattr(self, name)
            if isinstance(values, list) and values and len(values) != 2:
                raise ConfigurationError(f"{name} must hold 2 values (x, y), got {len(values)}")
        if bool(self.base_stiffness) != bool(self.base_damping):
            raise ConfigurationError("base_stiffness and base_damping go together")
        if any(X.base_frame for X in self.link_errors):
            raise ConfigurationError("link_errors: base_frame cannot be set (each is in its joint)")


@dataclass
class ModelErrors:
    """The error of a welded scene model (station.errors.models.<instance>).

    X_error: the model's true pose in the pose the directives weld it at (its weld's child
        frame; m, rad).
    """

    X_error: Transform = field(default_factory=Transform)

    def Validate(self) -> None:
        """Refuses a base_frame: X_error is relative to the weld's own child frame."""
        CheckFields(self)
        if self.X_error.base_frame:
            raise ConfigurationError("X_error.base_frame cannot be set (X_error is in the weld)")


@dataclass
class StationErrors:
    """station.errors: what the real cell has and the nominal models do not; empty: the
    exact cell.

    arms: ArmErrors per arm of station.arms.
    cameras: CameraErrors per camera of station.cameras.
    tof_tools: ToFErrors per tool of station.tof_tools.
    models: ModelErrors per welded model instance of the directives.
    """

    arms: dict[str, ArmErrors] = field(default_factory=dict)
    cameras: dict[str, CameraErrors] = field(default_factory=dict)
    tof_tools: dict[str, ToFErrors] = field(default_factory=dict)
    models: dict[str, ModelErrors] = field(default_factory=dict)


def PresetNames(errors_preset: str) -> list[str]:
    """The preset names of `errors_preset` ("NAME[,NAME...]"; '' none)."""
    return [name.strip() for name in errors_preset.split(",") if name.strip()]


def ListPresets() -> list[str]:
    """The names of models/errors/NAME.yaml."""
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def LoadPreset(name: str) -> StationErrors:
    """models/errors/NAME.yaml as StationErrors (ConfigurationError for an unknown one)."""
    path = PRESET_DIR / f"{name}.yaml"
    if not path.is_file():
        raise ConfigurationError(
            f"errors_preset: unknown preset '{name}' (known: {', '.join(ListPresets())})"
        )
    try:
        return yaml_load_typed(schema=StationErrors, filename=str(path))
    except Exception as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise ConfigurationError(f"errors preset {path}: {first}") from None


def CombinedErrors(errors_preset: str, errors: StationErrors) -> StationErrors:
    """The presets of `errors_preset` in order, then `errors`: a later entry's fields that
    differ from their defaults replace an earlier's (per arm, camera, tool and model)."""
    combined = StationErrors()
    for layer in [LoadPreset(n) for n in PresetNames(errors_preset)] + [errors]:
        for group in ("arms", "cameras", "tof_tools", "models"):
            target = getattr(combined, group)
            for key, entry in getattr(layer, group).items():
                target[key] = _Overridden(target.get(key), entry)
    return combined


def DrawStationErrors(errors_preset: str, errors: StationErrors, random_seed: int | None):
    """The presets and errors combined (CombinedErrors) with every distribution drawn from
    `random_seed` (DrawErrors; None refuses distributions), each entry validated."""
    drawn = DrawErrors(CombinedErrors(errors_preset, errors), random_seed)
    for group in ("arms", "cameras", "tof_tools"):
        for key, entry in getattr(drawn, group).items():
            try:
                entry.Validate()
            except ConfigurationError as e:
                raise ConfigurationError(f"errors.{group}.{key}: {e}") from None
    return drawn


def CheckErrorKeys(errors: StationErrors, known: dict[str, set[str]]) -> None:
    """Refuses an entry of errors.arms/cameras/tof_tools/models whose key names nothing in
    `known` (the station's arms, cameras, tools and model instances)."""
    for group, names in known.items():
        for key in getattr(errors, group):
            if key not in names:
                raise ConfigurationError(
                    f"errors.{group}.{key}: the station has no such {group[:-1]} "
                    f"(have {sorted(names)})"
                )


def ErrorsSummary(errors: StationErrors) -> dict[str, Any]:
    """The drawn errors as plain data for summary.json (fields at default left out)."""
    return ErrorsAsData(errors)


def HasErrors(errors: StationErrors) -> bool:
    """Whether drawn errors change anything in the cell."""
    return not IsZeroError(errors)


def DumpErrors(errors: StationErrors) -> str:
    """The errors as YAML (what a resolved scenario holds)."""
    return yaml_dump_typed(errors)


def _Overridden(base: Any, entry: Any) -> Any:
    if base is None:
        return entry
    default = type(entry)()
    changes = {
        f.name: getattr(entry, f.name)
        for f in dataclasses.fields(entry)
        if ErrorsAsData(_Only(entry, f.name)) != ErrorsAsData(_Only(default, f.name))
    }
    return dataclasses.replace(base, **changes)


def _Only(entry: Any, name: str) -> Any:
    """`entry`'s default type holding only field `name` of entry (for comparing one field,
    distributions included)."""
    return dataclasses.replace(type(entry)(), **{name: getattr(entry, name)})
