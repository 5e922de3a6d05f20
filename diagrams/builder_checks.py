"""Checks the public builders of diagrams/ make before they build anything.

CheckFieldTypes: a config made in Python (a StationScenario, a task scenario) whose fields
hold other types than declared, e.g. `arms=["ur10e"]` for a dict of ArmConfig, is refused
naming the dotted key, instead of an AttributeError deep inside the builder. A config
loaded from YAML has its types checked by its loading (scenario_loading.py).

CheckStationWiring: Drake finds a second connection into one input port, a port name the
station lacks, or a station left out of the builder only at Connect (a C++ "Failure at
...", or a RuntimeError listing every port), after the builder has already taken some of
the new systems: a half-wired builder the caller cannot use. CheckStationWiring refuses
all of these first, with one line naming the port.
"""

from __future__ import annotations

import dataclasses
import functools
import numbers
import types
import typing
from collections.abc import Iterable
from typing import Any

import numpy as np
from pydrake.systems.framework import DiagramBuilder, System

from guidedarm.systems.config_checks import CheckInstance, FieldError
from guidedarm.systems.errors import ConfigurationError


def CheckStationWiring(
    builder: DiagramBuilder,
    station: System,
    *,
    inputs: Iterable[str] = (),
    outputs: Iterable[str] = (),
    new_systems: Iterable[str] = (),
) -> None:
    """Refuses (ConfigurationError) wiring `station` into `builder` unless: `station` is a
    system of `builder`; it has every named output port and every named input port; each
    of those inputs is still free (neither connected nor exported: a Drake input takes one
    source); and `builder` has no system yet under any of the `new_systems` names."""
    CheckInstance("builder", builder, DiagramBuilder)
    CheckInstance("station", station, System)
    name = station.get_name()
    if not any(system is station for system in builder.GetSystems()):
        raise ConfigurationError(
            f"station '{name}' is not a system of this builder: add it first "
            '(builder.AddNamedSystem("station", station))'
        )
    for port in outputs:
        if not station.HasOutputPort(port):
            raise ConfigurationError(f"station '{name}' has no output port '{port}'")
    for port in inputs:
        if not station.HasInputPort(port):
            raise ConfigurationError(f"station '{name}' has no input port '{port}'")
        if builder.IsConnectedOrExported(station.GetInputPort(port)):
            raise ConfigurationError(
                f"station '{name}' input port '{port}' is already connected (an input takes "
                "one source)"
            )
    for system in new_systems:
        if builder.HasSubsystemNamed(system):
            raise ConfigurationError(f"the builder already has a system named '{system}'")


def CheckFieldTypes(config: Any, key: str) -> None:
    """Refuses (FieldError naming `key`.field) a dataclass whose fields, or the items of its
    list and dict fields, or the fields of its nested dataclasses, are not of their
    declared types. A list field may hold a tuple or a numpy array, a float field any real
    number (not a bool); Drake's structs are checked by their type only."""
    hints = _TypeHints(type(config))
    for field in dataclasses.fields(config):
        _CheckType(getattr(config, field.name), hints[field.name], f"{key}.{field.name}")


@functools.cache
def _TypeHints(config_type: type) -> dict[str, Any]:
    return typing.get_type_hints(config_type)


def _CheckType(value: Any, expected: Any, key: str) -> None:
    origin, args = typing.get_origin(expected), typing.get_args(expected)
    if origin in (typing.Union, types.UnionType):
        for member in args:
            try:
                _CheckType(value, member, key)
                return
            except FieldError:
                pass
        raise FieldError(key, f"expected {_TypeName(expected)}, got {value!r}")
    if origin is list:
        if not isinstance(value, list | tuple | np.ndarray):
            raise FieldError(key, f"expected {_TypeName(expected)}, got {value!r}")
        for i, item in enumerate(value):
            _CheckType(item, args[0], f"{key}[{i}]")
        return
    if origin is dict:
        if not isinstance(value, dict):
            raise FieldError(key, f"expected {_TypeName(expected)}, got {value!r}")
        for name, item in value.items():
            _CheckType(item, args[1], f"{key}.{name}")
        return
    admissible = {
        float: (numbers.Real,),
        int: (numbers.Integral,),
        bool: (bool, np.bool_),
        type(None): (type(None),),
    }.get(expected, (expected,) if isinstance(expected, type) else None)
    if admissible is None:  # an annotation without a runtime type (Any)
        return
    is_bool = isinstance(value, bool | np.bool_)
    if not isinstance(value, admissible) or (is_bool and expected in (float, int)):
        raise FieldError(key, f"expected {_TypeName(expected)}, got {value!r}")
    if dataclasses.is_dataclass(expected):
        CheckFieldTypes(value, key)


def _TypeName(expected: Any) -> str:
    origin, args = typing.get_origin(expected), typing.get_args(expected)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_TypeName(member) for member in args)
    if origin is list:
        return f"a list of {_TypeName(args[0])}"
    if origin is dict:
        return f"a dict of name: {_TypeName(args[1])}"
    if expected is type(None):
        return "None"
    return getattr(expected, "__name__", str(expected))
