"""The untyped walk of a scenario against its schema, before `yaml_load_typed`: every
error names the dotted key (Drake's don't) in one line.

Besides types and unknown keys it enforces what yaml_load_typed cannot: a text choice
(`typing.Literal`) holds one of its values, and a tagged union (a `Union` of dataclasses,
Drake's variant, e.g. an arm's `!NachiDriver {...}`) names a known type in its YAML tag;
an entry without a tag is the union's first type, as Drake reads it.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

from pydrake.common.yaml import yaml_dump, yaml_load_typed

from guidedarm.systems.config_checks import ChoiceViolation
from guidedarm.systems.errors import ConfigurationError


class ScenarioError(ConfigurationError):
    """A scenario file or override is malformed; the message names the file and the key."""


def CheckRawNode(schema: Any, value: Any, key: str, source: str) -> None:
    """Walks `value` against `schema` so that errors name the dotted key (Drake's don't)."""

    def fail(why: str) -> None:
        raise ScenarioError(f"{source}: key '{key or '<top>'}': {why}")

    origin = typing.get_origin(schema)
    if origin is typing.Literal:
        why = ChoiceViolation(value, schema)
        if why is not None:
            fail(why)
        return
    if origin in (typing.Union, types.UnionType):
        members = typing.get_args(schema)
        if value is None and type(None) in members:
            return
        if all(dataclasses.is_dataclass(m) for m in members):
            return _CheckVariant(members, value, key, source)
        errors = []
        for member in (m for m in members if m is not type(None)):
            try:
                CheckRawNode(member, value, key, source)
                return
            except ScenarioError as e:
                errors.append(str(e))
        fail(f"matches none of {[getattr(m, '__name__', str(m)) for m in members]}")
    if origin is list:
        if not isinstance(value, list):
            fail(f"expected a list, got {value!r}")
        (item_schema,) = typing.get_args(schema) or (Any,)
        for i, item in enumerate(value):
            CheckRawNode(item_schema, item, f"{key}[{i}]", source)
        return
    if origin is dict:
        if not isinstance(value, dict):
            fail(f"expected a mapping, got {value!r}")
        _, item_schema = typing.get_args(schema) or (str, Any)
        for name, item in value.items():
            CheckRawNode(item_schema, item, JoinKey(key, str(name)), source)
        return
    if dataclasses.is_dataclass(schema):
        if not isinstance(value, dict):
            fail(f"expected a mapping of {schema.__name__} fields, got {value!r}")
        hints = typing.get_type_hints(schema)
        known = {f.name for f in dataclasses.fields(schema)}
        for name, item in value.items():
            if name not in known:
                raise ScenarioError(
                    f"{source}: unknown key '{JoinKey(key, name)}' "
                    f"(known keys: {', '.join(sorted(known))})"
                )
            CheckRawNode(hints[name], item, JoinKey(key, name), source)
        return
    if schema is bool:
        if not isinstance(value, bool):
            fail(f"expected true or false, got {value!r}")
    elif schema is float:
        number = isinstance(value, int | float) or (isinstance(value, str) and _is_number(value))
        if isinstance(value, bool) or not number:
            fail(f"expected a number, got {value!r}")
    elif schema is int:
        if isinstance(value, bool) or not isinstance(value, int):
            fail(f"expected an integer, got {value!r}")
    elif schema is str:
        if not isinstance(value, str):
            fail(f"expected a string, got {value!r}")
    elif hasattr(schema, "__fields__"):
        _check_bound_struct(schema, value, key, source)


def _CheckVariant(members: tuple[type, ...], value: Any, key: str, source: str) -> None:
    """A tagged union (Drake's variant): the YAML tag `!Name` picks the dataclass `Name`;
    without a tag the value is the first one."""
    tag = value.get("_tag") if isinstance(value, dict) else None
    tags = [f"!{m.__name__}" for m in members]
    if tag is None:
        try:
            CheckRawNode(members[0], value, key, source)
        except ScenarioError as e:
            others = " or ".join(f"{t} {{...}}" for t in tags[1:])
            raise ScenarioError(
                f"{e} (an entry without a YAML tag is a {tags[0]}; for another type write "
                f"its tag, {others})"
            ) from None
        return
    chosen = [m for m, t in zip(members, tags, strict=True) if t == tag]
    if not chosen:
        raise ScenarioError(f"{source}: key '{key}': unknown tag {tag} (known: {', '.join(tags)})")
    rest = {name: item for name, item in value.items() if name != "_tag"}
    CheckRawNode(chosen[0], rest, key, source)


def _check_bound_struct(schema: Any, value: Any, key: str, source: str) -> None:
    """Drake's C++ structs (CameraConfig, Transform, ...): check field by field."""
    if not isinstance(value, dict):
        raise ScenarioError(f"{source}: key '{key}': expected a mapping of {schema.__name__}")
    fields = {f.name: f.type for f in schema.__fields__}
    for name, item in value.items():
        if name == "_tag":
            continue
        if name not in fields:
            raise ScenarioError(
                f"{source}: unknown key '{JoinKey(key, name)}' "
                f"(known keys: {', '.join(sorted(fields))})"
            )
        if hasattr(fields[name], "__fields__"):
            _check_bound_struct(fields[name], item, JoinKey(key, name), source)
            continue
        try:
            yaml_load_typed(schema=schema, data=yaml_dump({name: item}))
        except Exception as e:
            text = FirstLine(e)
            if "incompatible function arguments" in text:
                text = f"wrong shape or type: {item!r}"
            raise ScenarioError(f"{source}: key '{JoinKey(key, name)}': {text}") from None


def _is_number(text: str) -> bool:
    """Whether YAML text that was read as a string is a number (`1e-3`, `nan`)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def JoinKey(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def FirstLine(error: Exception) -> str:
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    return lines[0] if lines else type(error).__name__
