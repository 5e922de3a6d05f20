"""Declared bounds of config fields, and the walk that checks a typed config tree.

Every scenario, camera and panel file is checked by CheckConfig right after its typed load
(diagrams/scenario_loading.py), before any model is built. The rules:
  - every float is finite, unless its field is declared with `allow_inf=True` (and its doc
    says what infinity means);
  - every int is >= 0 (our ints are seeds, counts, indices, sizes and ports), unless its
    field declares another bound;
  - a field declared with Positive, NonNegative or InRange meets that bound (every element,
    for a list field);
  - a dataclass field holds a value of its annotated type (a config made in Python may
    hold 2.5 for an int or "3" for a float): an int is an int (not a bool), a float an int
    or a float (not a bool), a bool a bool, a str a str, list[T] a list (tuple, array) of
    T, dict[K, V] a dict of V, `T | None` None or a T, a config class an instance of it;
    other annotations are not checked;
  - Drake's structs inside a schema (MultibodyPlantConfig, SimulatorConfig, CameraConfig,
    Transform, ...) are walked the same way, with the bounds of DRAKE_BOUNDS and the
    checks of DRAKE_CHECKS;
  - a dataclass with a `Validate()` method is checked by it: Validate() calls
    CheckFields(self) first, then checks the rules between its fields.
Every comparison is written so that NaN fails it (`not value > low`).
Errors are FieldError: one line naming the dotted key, e.g. `key 'station.arms.ur10e.kp':
must be > 0, got nan`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import types
import typing
from collections.abc import Callable
from dataclasses import MISSING, dataclass
from typing import Any

import numpy as np
from pydrake.geometry import Rgba
from pydrake.multibody.plant import MultibodyPlantConfig
from pydrake.systems.analysis import GetIntegrationSchemes, SimulatorConfig
from pydrake.systems.sensors import CameraConfig
from pydrake.visualization import VisualizationConfig

from guidedarm.systems.errors import ConfigurationError

_BOUND = "guidedarm.bound"


class FieldError(ConfigurationError):
    """A config value is out of its bounds; `key` is its dotted path in the config tree."""

    def __init__(self, key: str, why: str) -> None:
        self.key = key
        self.why = why
        super().__init__(f"key '{key}': {why}" if key else why)


@dataclass(frozen=True)
class Bound:
    """An interval for a number (both ends included unless open), and whether +-inf is
    admissible."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    allow_inf: bool = False

    def Violation(self, value: float) -> str | None:
        """Why `value` is out of bounds, or None; NaN is always out."""
        if not (self.allow_inf or math.isfinite(value)):
            return f"must be a finite number, got {value}"
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        if not (above and below):
            return f"must be {self}, got {value}"
        return None

    def __str__(self) -> str:
        if self.high == math.inf:
            return f"{'>' if self.low_open else '>='} {self.low:g}"
        if self.low == -math.inf:
            return f"{'<' if self.high_open else '<='} {self.high:g}"
        left, right = "(" if self.low_open else "[", ")" if self.high_open else "]"
        return f"in {left}{self.low:g}, {self.high:g}{right}"


FINITE = Bound()
POSITIVE = Bound(low=0.0, low_open=True)
NON_NEGATIVE = Bound(low=0.0)
UNIT_INTERVAL = Bound(low=0.0, high=1.0)
# A joint position (rad) beyond two turns either way is no joint of our arms (UR10e joints
# span +-2 pi); it bounds every joint vector of a scenario.
MAX_JOINT_POSITION = 4 * math.pi
# The most pixels a camera renders (width x height, after supersampling): 64 MP, above
# the 1920 x 1080 x 3^2 = 18.7 MP of the shipped panel camera; beyond, VTK's buffers fail.
MAX_RENDER_PIXELS = 64_000_000


def Positive(default: Any = MISSING, *, factory: Any = MISSING, allow_inf: bool = False) -> Any:
    """A dataclass field whose value (or each element) must be > 0."""
    return Bounded(Bound(low=0.0, low_open=True, allow_inf=allow_inf), default, factory)


def NonNegative(default: Any = MISSING, *, factory: Any = MISSING) -> Any:
    """A dataclass field whose value (or each element) must be >= 0."""
    return Bounded(NON_NEGATIVE, default, factory)


def InRange(
    low: float,
    high: float,
    default: Any = MISSING,
    *,
    factory: Any = MISSING,
    low_open: bool = False,
    high_open: bool = False,
) -> Any:
    """A dataclass field whose value (or each element) must lie between low and high."""
    return Bounded(Bound(low, high, low_open, high_open), default, factory)


def Bounded(bound: Bound, default: Any = MISSING, factory: Any = MISSING) -> Any:
    """A dataclass field carrying `bound` (see the module docstring)."""
    return dataclasses.field(default=default, default_factory=factory, metadata={_BOUND: bound})


def CheckConfig(config: Any, key: str = "") -> None:
    """Checks a whole typed config tree (see the module docstring); raises FieldError with
    the dotted key prefixed by `key`."""
    try:
        _CheckValue(config, None)
    except ConfigurationError as e:
        raise _Under(key, e) from None


def CheckFields(config: Any) -> None:
    """Checks the fields of one dataclass or Drake struct: declared types (a config made in
    Python may hold "false", which is truthy, or 2.5 for a count), declared bounds,
    finiteness, and every nested config (through its own Validate() when it has one)."""
    hints = _TypeHints(type(config)) if dataclasses.is_dataclass(config) else {}
    for name, value, bound in _Fields(config):
        try:
            if name in hints:
                _CheckType(value, hints[name])
            _CheckValue(value, bound)
        except ConfigurationError as e:
            raise _Under(name, e) from None


def ChangedKey(value: object, default: object, key: str) -> str:
    """The dotted name of the first field of `value` (a dataclass or a Drake struct) that
    differs from `default`, or ''."""
    if dataclasses.is_dataclass(value):
        names = [f.name for f in dataclasses.fields(value)]
    elif hasattr(type(value), "__fields__"):
        names = [f.name for f in type(value).__fields__]
    else:
        return "" if np.array_equal(value, default) else key
    for name in names:
        changed = ChangedKey(getattr(value, name), getattr(default, name), f"{key}.{name}")
        if changed:
            return changed
    return ""


def CheckArgument(name: str, value: Any, bound: Bound) -> None:
    """Checks a number argument of a public builder against `bound`; raises FieldError
    naming the argument (a bool or a non-number is refused too)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise FieldError(name, f"expected a number, got {value!r}")
    try:
        _CheckNumber(float(value), bound)
    except ConfigurationError as e:
        raise _Under(name, e) from None


def CheckVector(
    name: str, value: Any, size: int | None = None, bound: Bound = FINITE
) -> np.ndarray:
    """Checks a vector argument of a public builder (joint positions, weights, a point):
    `size` numbers (any size if None), each within `bound`; returns it as a float array.
    Raises FieldError naming the argument (and the element)."""
    try:
        vector = np.asarray(value, float)
    except (TypeError, ValueError):
        vector = None
    if vector is None or vector.ndim != 1 or (size is not None and len(vector) != size):
        count = "numbers" if size is None else f"{size} numbers"
        raise FieldError(name, f"expected a vector of {count}, got {value!r}")
    for i, item in enumerate(vector.tolist()):
        try:
            _CheckNumber(item, bound)
        except ConfigurationError as e:
            raise _Under(f"{name}[{i}]", e) from None
    return vector


def CheckInstance(name: str, value: Any, expected: type | tuple[type, ...]) -> None:
    """Checks the type of an argument of a public builder (a scenario, a plant, a frame);
    raises FieldError naming the argument and the type expected (None passes where
    `expected` includes type(None))."""
    if not isinstance(value, expected):
        types = expected if isinstance(expected, tuple) else (expected,)
        names = " or ".join("None" if t is type(None) else t.__name__ for t in types)
        raise FieldError(name, f"expected {names}, got {value!r}")


def CheckNames(name: str, value: Any) -> None:
    """Checks that an argument is a list (or tuple) of strings, not one string, whose
    characters would be taken for names."""
    if isinstance(value, str) or not isinstance(value, list | tuple):
        raise FieldError(name, f"expected a list of names, got {value!r}")
    for i, item in enumerate(value):
        if not isinstance(item, str):
            raise FieldError(f"{name}[{i}]", f"expected a name, got {item!r}")


@functools.cache
def _TypeHints(cls: type) -> dict[str, Any]:
    """The resolved field annotations of a dataclass type ({} if they cannot be resolved)."""
    try:
        return typing.get_type_hints(cls)
    except Exception:  # a name imported for type checking only: leave its fields unchecked
        return {}


def _CheckType(value: Any, annotation: Any) -> None:
    """Raises FieldError (key: the element's index, if any) unless `value` holds the type
    `annotation` (see the module docstring)."""
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return
        errors = []
        for option in (a for a in args if a is not type(None)):
            try:
                return _CheckType(value, option)
            except FieldError as e:
                errors.append(e)
        raise errors[0]
    why = _Mismatch(value, annotation, origin)
    if why is not None:
        raise FieldError("", why)
    if origin in (list, dict) and args:
        items = value.items() if origin is dict else enumerate(value)
        for key, item in items:
            try:
                _CheckType(item, args[-1])
            except FieldError as e:
                raise _Under(f"[{key}]" if origin is list else str(key), e) from None


def _Mismatch(value: Any, annotation: Any, origin: Any) -> str | None:
    """Why `value` is not of the outer type of `annotation`, or None."""
    number = isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)
    if annotation is bool and not isinstance(value, bool | np.bool_):
        return f"expected true or false, got {value!r}"
    if annotation is int and not (number and isinstance(value, numbers.Integral)):
        return f"expected an integer, got {value!r}"
    if annotation is float and not number:
        return f"expected a number, got {value!r}"
    if annotation is str and not isinstance(value, str):
        return f"expected a string, got {value!r}"
    if origin is list and (not isinstance(value, list | tuple | np.ndarray) or np.ndim(value) == 0):
        return f"expected a list, got {value!r}"
    if origin is dict and not isinstance(value, dict):
        return f"expected a mapping, got {value!r}"
    config_class = isinstance(annotation, type) and (
        dataclasses.is_dataclass(annotation) or hasattr(annotation, "__fields__")
    )
    if config_class and not isinstance(value, annotation):
        return f"expected {annotation.__name__}, got {value!r}"
    return None


def _Fields(config: Any) -> list[tuple[str, Any, Bound | None]]:
    if dataclasses.is_dataclass(config):
        return [
            (f.name, getattr(config, f.name), f.metadata.get(_BOUND))
            for f in dataclasses.fields(config)
        ]
    bounds = DRAKE_BOUNDS.get(type(config), {})
    return [(f.name, getattr(config, f.name), bounds.get(f.name)) for f in type(config).__fields__]


def _CheckValue(value: Any, bound: Bound | None) -> None:
    if value is None or isinstance(value, str | bool):
        return
    if isinstance(value, numbers.Integral):
        _CheckNumber(int(value), bound or NON_NEGATIVE)
    elif isinstance(value, numbers.Real):
        _CheckNumber(float(value), bound or FINITE)
    elif isinstance(value, np.ndarray | list | tuple):
        items = value.ravel().tolist() if isinstance(value, np.ndarray) else value
        for i, item in enumerate(items):
            try:
                _CheckValue(item, bound)
            except ConfigurationError as e:
                raise _Under(f"[{i}]", e) from None
    elif isinstance(value, dict):
        for name, item in value.items():
            try:
                _CheckValue(item, bound)
            except ConfigurationError as e:
                raise _Under(str(name), e) from None
    elif dataclasses.is_dataclass(value) or hasattr(type(value), "__fields__"):
        validate = getattr(value, "Validate", None)
        if callable(validate):
            validate()
        else:
            CheckFields(value)
        extra = DRAKE_CHECKS.get(type(value))
        if extra is not None:
            extra(value)


def _CheckNumber(value: float, bound: Bound) -> None:
    why = bound.Violation(value)
    if why is not None:
        raise FieldError("", why)


def _Under(prefix: str, error: ConfigurationError) -> FieldError:
    if not isinstance(error, FieldError):
        return FieldError(prefix, str(error))
    if not prefix:
        return error
    if not error.key:
        return FieldError(prefix, error.why)
    joiner = "" if error.key.startswith("[") else "."
    return FieldError(f"{prefix}{joiner}{error.key}", error.why)


def _CheckCamera(config: CameraConfig) -> None:
    CheckRenderSize(config, 1)
    try:
        config.MakeCameras()
    except Exception as e:  # Drake lists every problem, one per line
        raise FieldError("", " ".join(str(e).split())) from None


def CheckRenderSize(config: CameraConfig, supersampling: int, key: str = "") -> None:
    """Refuses a camera whose rendered image (width x height x supersampling^2) exceeds
    MAX_RENDER_PIXELS; `key` names the supersampling in the message."""
    pixels = config.width * config.height * supersampling**2
    if pixels > MAX_RENDER_PIXELS:
        by = f" x {key}^2 ({supersampling**2})" if key else ""
        raise FieldError(
            "",
            f"renders {config.width} x {config.height}{by} = {pixels:,} pixels, more than "
            f"{MAX_RENDER_PIXELS:,}",
        )


def _CheckPlantConfig(config: MultibodyPlantConfig) -> None:
    # Drake reads these names only when a plant is built; an empty one checks them.
    from pydrake.multibody.plant import AddMultibodyPlant
    from pydrake.systems.framework import DiagramBuilder

    try:
        AddMultibodyPlant(config, DiagramBuilder())
    except Exception as e:
        raise FieldError("", str(e).strip().splitlines()[0]) from None


def _CheckSimulatorConfig(config: SimulatorConfig) -> None:
    schemes = GetIntegrationSchemes()
    if config.integration_scheme not in schemes:
        raise FieldError(
            "integration_scheme",
            f"unknown scheme '{config.integration_scheme}' (known: {', '.join(schemes)})",
        )


# Bounds of the numeric fields of Drake's structs used inside our schemas (their floats
# are finite and their ints >= 0 by the general rules): a plant steps at most 0.1 s (0
# is continuous), a camera is at most 16384 pixels wide or high.
DRAKE_BOUNDS: dict[type, dict[str, Bound]] = {
    MultibodyPlantConfig: {
        "time_step": Bound(0.0, 0.1),
        "penetration_allowance": POSITIVE,
        "stiction_tolerance": POSITIVE,
        "sap_near_rigid_threshold": NON_NEGATIVE,
    },
    SimulatorConfig: {
        "max_step_size": POSITIVE,
        "accuracy": POSITIVE,
        "start_time": NON_NEGATIVE,
        "target_realtime_rate": NON_NEGATIVE,
    },
    CameraConfig: {
        "width": Bound(1, 16384),
        "height": Bound(1, 16384),
        "clipping_near": POSITIVE,
        "clipping_far": POSITIVE,
        "z_near": POSITIVE,
        "z_far": POSITIVE,
        "fps": POSITIVE,
        "capture_offset": NON_NEGATIVE,
        "output_delay": NON_NEGATIVE,
    },
    CameraConfig.FocalLength: {"x": POSITIVE, "y": POSITIVE},
    CameraConfig.FovDegrees: {
        "x": Bound(0.0, 180.0, True, True),
        "y": Bound(0.0, 180.0, True, True),
    },
    VisualizationConfig: {"publish_period": POSITIVE, "initial_proximity_alpha": UNIT_INTERVAL},
    Rgba: {"rgba": UNIT_INTERVAL},
}

# Rules between the fields of Drake's structs, checked after their bounds.
DRAKE_CHECKS: dict[type, Callable[[Any], None]] = {
    CameraConfig: _CheckCamera,
    MultibodyPlantConfig: _CheckPlantConfig,
    SimulatorConfig: _CheckSimulatorConfig,
}
