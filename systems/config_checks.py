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
  - a text choice is annotated `typing.Literal["a", "b"]` and holds one of its values;
    its class is decorated with TextChoices, which lets pydrake's yaml_load_typed (that
    knows no Literal) read the field as a str;
  - Drake's structs inside a schema (MultibodyPlantConfig, SimulatorConfig, CameraConfig,
    Transform, ...) are walked the same way, with the bounds of DRAKE_BOUNDS and the
    checks of DRAKE_CHECKS;
  - a dataclass with a `Validate()` method is checked by it: Validate() calls
    CheckFields(self) first, then checks the rules between its fields.
Every comparison is written so that NaN fails it (`not value > low`). The bounds are
declared with systems/config_bounds.py, those of Drake's structs in
systems/drake_config_checks.py.
Errors are FieldError: one line naming the dotted key, e.g. `key 'station.arms.ur10e.kp':
must be > 0, got nan`.
"""

from __future__ import annotations

import dataclasses
import functools
import numbers
import types
import typing
from typing import Any

import numpy as np

from guidedarm.systems.config_bounds import (
    BOUND_KEY,
    FINITE,
    MAX_JOINT_POSITION,
    NON_NEGATIVE,
    POSITIVE,
    Bound,
    Bounded,
    FieldError,
    InRange,
    NonNegative,
    Positive,
)
from guidedarm.systems.drake_config_checks import DRAKE_BOUNDS, DRAKE_CHECKS
from guidedarm.systems.errors import ConfigurationError

# The field helpers and bounds are used with the checks: one import for both.
__all__ = [
    "FINITE",
    "MAX_JOINT_POSITION",
    "NON_NEGATIVE",
    "POSITIVE",
    "Bound",
    "Bounded",
    "ChangedKey",
    "CheckArgument",
    "CheckConfig",
    "CheckFields",
    "CheckInstance",
    "CheckNames",
    "CheckVector",
    "ChoiceViolation",
    "FieldError",
    "InRange",
    "NonNegative",
    "Positive",
    "TextChoices",
]


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


def TextChoices(cls: type) -> type:
    """Class decorator of a config dataclass whose text choices are `typing.Literal`
    fields: pydrake's yaml_load_typed reads a field by its dataclass Field.type and knows
    no Literal, so that type becomes `str` (or `str | None`); the annotation keeps the
    Literal, which CheckFields enforces (a value outside it is refused naming the key and
    the values allowed)."""
    for f in dataclasses.fields(cls):
        hint = f.type
        optional = typing.get_origin(hint) in (typing.Union, types.UnionType)
        inner = [a for a in typing.get_args(hint) if a is not type(None)] if optional else [hint]
        if len(inner) == 1 and typing.get_origin(inner[0]) is typing.Literal:
            f.type = str | None if optional else str
    return cls


def ChoiceViolation(value: Any, annotation: Any) -> str | None:
    """Why `value` is not one of the values of the `typing.Literal` annotation, or None
    (also None when `annotation` is no Literal)."""
    if typing.get_origin(annotation) is not typing.Literal:
        return None
    choices = typing.get_args(annotation)
    if value in choices and isinstance(value, str):
        return None
    return f"{value!r} is not one of {', '.join(repr(c) for c in choices)}"


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
        options = [a for a in args if a is not type(None)]
        if all(dataclasses.is_dataclass(a) for a in options) and not isinstance(
            value, tuple(options)
        ):  # a tagged union (Drake's variant) holds one of its classes
            names = " or ".join(a.__name__ for a in options)
            raise FieldError("", f"expected {names}, got {value!r}")
        errors = []
        for option in options:
            try:
                return _CheckType(value, option)
            except FieldError as e:
                errors.append(e)
        raise errors[0]
    why = ChoiceViolation(value, annotation) or _Mismatch(value, annotation, origin)
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
            (f.name, getattr(config, f.name), f.metadata.get(BOUND_KEY))
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
