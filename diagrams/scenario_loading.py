"""Loading scenario files: named scenarios, `--set key=value` overrides, typed schemas.

A scenario file is YAML whose top level names its `task` and whose remaining keys are the
fields of that task's scenario dataclass. Loading is two passes: an untyped read (which keeps
Drake's YAML tags such as `!Rpy`) to apply the command-line overrides and find the task, then
`yaml_load_typed` against the task's dataclass, which rejects unknown keys and wrong types.
The typed result then goes through systems/config_checks.py (finite numbers, declared
bounds, each config's Validate()) before anything is built from it.

A key given twice is refused wherever user YAML comes in (RefuseDuplicateKeys): in a file
(scenario, campaign, camera, panel, hose workspace), in a `--set` value, and as two `--set`
items for one key or for a key and a part of it. YAML readers keep the last value silently.

Numbers may be written in exponent notation (`1e-3`, `1.5e1`): YAML 1.1 reads those as
strings; a float field accepts them and `yaml_load_typed` converts them, as Drake's own
loading of a scenario file does.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import types
import typing
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TypeVar

from pydrake.common.yaml import yaml_dump, yaml_load_data, yaml_load_typed

from guidedarm.diagrams.yaml_duplicates import FindDuplicateKey
from guidedarm.systems.config_checks import CheckConfig, FieldError
from guidedarm.systems.errors import ConfigurationError

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"

T = TypeVar("T")


class ScenarioError(ConfigurationError):
    """A scenario file or override is malformed; the message names the file and the key."""


def resolve_scenario_path(name_or_path: str) -> Path:
    """Returns the YAML file for a named scenario (diagrams/scenarios/NAME.yaml) or a path."""
    return ResolveNamedFile(name_or_path, SCENARIO_DIR, "scenario", ScenarioError)


def list_named_scenarios() -> list[str]:
    """Names of the scenarios shipped in diagrams/scenarios/."""
    return ListNamedFiles(SCENARIO_DIR)


def ResolveNamedFile(name_or_path: str, folder: Path, kind: str, error: type[Exception]) -> Path:
    """A YAML file given as a path, or by the NAME of folder/NAME.yaml; raises `error`
    naming the known names when there is none."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml"):
        if not path.is_file():
            raise error(f"{kind} file not found: {path}")
        return path
    named = folder / f"{name_or_path}.yaml"
    if not named.is_file():
        known = ", ".join(ListNamedFiles(folder))
        raise error(f"unknown {kind} '{name_or_path}' (known: {known})")
    return named


def ListNamedFiles(folder: Path) -> list[str]:
    """The NAMEs of folder/NAME.yaml."""
    return sorted(p.stem for p in folder.glob("*.yaml"))


def AddOverridesArgument(parser: argparse.ArgumentParser, help: str) -> None:
    """Adds the repeatable `--set KEY=VALUE` option (into `args.overrides`) to a command."""
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=help
    )


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """Parses a list of `key=value` strings (FieldError naming `overrides` for anything
    else, e.g. one string); values are read as YAML scalars or flow collections. A key
    given twice, or beside a part of it (`a` and `a.b`), is refused: one of the values
    would be dropped silently."""
    if isinstance(items, str) or not isinstance(items, list | tuple):
        raise FieldError("overrides", f"expected a list of 'key=value' strings, got {items!r}")
    for i, item in enumerate(items):
        if not isinstance(item, str):
            raise FieldError(f"overrides[{i}]", f"expected a 'key=value' string, got {item!r}")
    overrides: dict[str, Any] = {}
    given: dict[str, list[str]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not re.fullmatch(r"[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*", key):
            raise ScenarioError(f"--set expects key=value (dotted keys allowed), got '{item}'")
        text = f"value: {value}"
        try:
            overrides[key] = yaml_load_data(text)["value"]
        except Exception as e:  # the YAML parser's own message is the useful part
            raise ScenarioError(
                f"--set {key}: cannot parse value '{value}': {_first_line(e)}"
            ) from None
        RefuseDuplicateKeys(value, f"--set {key}", lines=False)
        given.setdefault(key, []).append(value)
    _RefuseRepeatedOverrides(given)
    return overrides


def _RefuseRepeatedOverrides(given: dict[str, list[str]]) -> None:
    """Refuses a --set key given more than once, and a key given beside a part of it
    (`a` and `a.b`: `a` replaces the part given before it and merges with one after)."""
    for key, values in given.items():
        if len(values) > 1:
            raise ScenarioError(
                f"--set {key} given {_Times(len(values))} ({', '.join(values)}): give it once"
            )
    keys = list(given)
    for i, first in enumerate(keys):
        for second in keys[i + 1 :]:
            if first.startswith(f"{second}.") or second.startswith(f"{first}."):
                raise ScenarioError(
                    f"--set {first} and --set {second} both given: set the whole value or "
                    "its parts, not both"
                )


def apply_overrides(raw: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """Returns a copy of the untyped scenario with each dotted key set to its value."""
    result = dict(raw)
    for dotted, value in overrides.items():
        node = result
        parts = dotted.split(".")
        for part in parts[:-1]:
            child = node.get(part)
            child = dict(child) if isinstance(child, dict) else {}
            node[part] = child
            node = child
        node[parts[-1]] = value
    return result


def read_raw_scenario(path: Path) -> dict[str, Any]:
    """Reads a YAML file of mappings (a scenario, campaign, camera, panel or hose workspace
    file) without a schema; fails with a one-line message if it is malformed or gives a
    key twice (RefuseDuplicateKeys)."""
    try:
        text = Path(path).read_text()
        raw = yaml_load_data(text)
    except Exception as e:
        raise ScenarioError(f"{path}: malformed YAML: {_first_line(e)}") from None
    RefuseDuplicateKeys(text, str(path))
    if not isinstance(raw, dict):
        raise ScenarioError(f"{path}: the top level must be a mapping of scenario keys")
    return raw


def RefuseDuplicateKeys(text: str, source: str, lines: bool = True) -> None:
    """Refuses (ScenarioError) YAML `text` that gives one key twice in a mapping, naming
    `source`, the key's dotted path and (with `lines`) the 1-based lines it is on: YAML
    readers (PyYAML, and Drake's on top of it) keep the last value without a word. The
    text must parse (read it first)."""
    duplicate = FindDuplicateKey(text)
    if duplicate is None:
        return
    key, where = duplicate
    text = f"{source}: key '{key}' appears {_Times(len(where))}"
    if lines:
        numbers = [str(n) for n in where]
        text += (
            f" (line {numbers[0]})"
            if len(set(numbers)) == 1
            else f" (lines {', '.join(numbers[:-1])} and {numbers[-1]})"
        )
    raise ScenarioError(text)


def _Times(count: int) -> str:
    return "twice" if count == 2 else f"{count} times"


# Keys a scenario no longer has, and what replaced them: a scenario has one `random_seed`
# from which every component draws its own stream (ToF noise, start pose, image noise); a
# component's own seed left in a scenario (e.g. `degradation.seed`) must agree with it.
REPLACED_KEYS = {
    "seed": "random_seed",
    "repeat_seed": "repeat_random_seed",
    "start.seed": "random_seed",
}


# Keys of a station's ToF tools that moved to station.errors (what the real sensors read
# differently from the truth): station.tof_tools.<tool>.KEY -> station.errors.tof_tools.<tool>.KEY.
MOVED_TOF_KEYS = ("offset", "drift_rate", "drift_max")


def _refuse_moved_keys(raw: dict[str, Any], source: str) -> None:
    """A ToF tool key of MOVED_TOF_KEYS under station.tof_tools is refused naming its new
    place under station.errors."""
    station = raw.get("station")
    tools = station.get("tof_tools") if isinstance(station, dict) else None
    for name, tool in (tools or {}).items() if isinstance(tools, dict) else ():
        for key in MOVED_TOF_KEYS:
            if isinstance(tool, dict) and key in tool:
                raise ScenarioError(
                    f"{source}: key 'station.tof_tools.{name}.{key}' moved to "
                    f"'station.errors.tof_tools.{name}.{key}' (the real sensor's errors)"
                )


def load_typed(
    schema: type[T], raw: dict[str, Any], source: str, overridden: Iterable[str] = ()
) -> T:
    """Loads `raw` into the dataclass `schema` and checks it (CheckConfig), naming the
    offending key on failure, and `--set` instead of `source` for a key in (or under) one
    of the `overridden` dotted keys."""
    try:
        _refuse_replaced_keys(schema, raw, source)
        _refuse_moved_keys(raw, source)
        _check_node(schema, raw, "", source)
        try:
            typed = yaml_load_typed(schema=schema, data=yaml_dump(raw))
        except Exception as e:
            raise ScenarioError(f"{source}: {_first_line(e)}") from None
        try:
            CheckConfig(typed)
        except ConfigurationError as e:
            raise ScenarioError(f"{source}: {e}") from None
    except ScenarioError as e:
        raise _NamingTheOverride(e, source, list(overridden)) from None
    return typed


def _NamingTheOverride(error: ScenarioError, source: str, overridden: list[str]) -> ScenarioError:
    """`error` ("SOURCE: key 'K': ...") as "--set key 'K': ..." when K came from --set, and
    as "SOURCE with --set K.x: key 'K': ..." when a rule between K's fields refuses it and
    some of them came from --set. A check that names the key first ("SOURCE: K must be
    ...") becomes "--set K must be ..." when K came from --set."""
    text = str(error)
    named = re.match(re.escape(source) + r": (?:unknown )?key '([^']*)'", text)
    if named is None:
        leading = re.match(re.escape(source) + r": ([\w.]+)\b", text)
        if leading and _IsOverridden(leading.group(1), overridden):
            return ScenarioError("--set " + text[len(source) + 2 :])
        return error
    key = named.group(1)
    if _IsOverridden(key, overridden):
        return ScenarioError("--set " + text[len(source) + 2 :])
    inside = [k for k in overridden if k.startswith((f"{key}.", f"{key}["))]
    field = re.match(r"([\w.]+)\b", text[named.end() + 2 :])
    if field and _IsOverridden(f"{key}.{field.group(1)}", overridden):
        return ScenarioError(f"--set {key}.{text[named.end() + 2 :]}")
    if inside:
        return ScenarioError(f"{source} with --set {', '.join(inside)}: {text[len(source) + 2 :]}")
    return error


def _IsOverridden(key: str, overridden: list[str]) -> bool:
    """Whether the dotted `key` is one of the `overridden` keys or lies under one."""
    return any(key == k or key.startswith((f"{k}.", f"{k}[")) for k in overridden)


def _refuse_replaced_keys(schema: Any, raw: dict[str, Any], source: str) -> None:
    """A key of REPLACED_KEYS is refused naming its replacement (for task scenarios, which
    have a `random_seed`)."""
    if not (dataclasses.is_dataclass(schema) and "random_seed" in schema.__dataclass_fields__):
        return
    for dotted, replacement in REPLACED_KEYS.items():
        node: Any = raw
        for part in dotted.split("."):
            node = node.get(part, _MISSING) if isinstance(node, dict) else _MISSING
        if node is not _MISSING:
            raise ScenarioError(
                f"{source}: key '{dotted}' was replaced by '{replacement}' (one random seed per "
                "scenario; every component draws its own stream from it)"
            )


_MISSING = object()


def _check_node(schema: Any, value: Any, key: str, source: str) -> None:
    """Walks `value` against `schema` so that errors name the dotted key (Drake's don't)."""

    def fail(why: str) -> None:
        raise ScenarioError(f"{source}: key '{key or '<top>'}': {why}")

    origin = typing.get_origin(schema)
    if origin in (typing.Union, types.UnionType):
        members = typing.get_args(schema)
        if value is None and type(None) in members:
            return
        errors = []
        for member in (m for m in members if m is not type(None)):
            try:
                _check_node(member, value, key, source)
                return
            except ScenarioError as e:
                errors.append(str(e))
        fail(f"matches none of {[getattr(m, '__name__', str(m)) for m in members]}")
    if origin is list:
        if not isinstance(value, list):
            fail(f"expected a list, got {value!r}")
        (item_schema,) = typing.get_args(schema) or (Any,)
        for i, item in enumerate(value):
            _check_node(item_schema, item, f"{key}[{i}]", source)
        return
    if origin is dict:
        if not isinstance(value, dict):
            fail(f"expected a mapping, got {value!r}")
        _, item_schema = typing.get_args(schema) or (str, Any)
        for name, item in value.items():
            _check_node(item_schema, item, _join(key, str(name)), source)
        return
    if dataclasses.is_dataclass(schema):
        if not isinstance(value, dict):
            fail(f"expected a mapping of {schema.__name__} fields, got {value!r}")
        hints = typing.get_type_hints(schema)
        known = {f.name for f in dataclasses.fields(schema)}
        for name, item in value.items():
            if name not in known:
                raise ScenarioError(
                    f"{source}: unknown key '{_join(key, name)}' "
                    f"(known keys: {', '.join(sorted(known))})"
                )
            _check_node(hints[name], item, _join(key, name), source)
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
                f"{source}: unknown key '{_join(key, name)}' "
                f"(known keys: {', '.join(sorted(fields))})"
            )
        if hasattr(fields[name], "__fields__"):
            _check_bound_struct(fields[name], item, _join(key, name), source)
            continue
        try:
            yaml_load_typed(schema=schema, data=yaml_dump({name: item}))
        except Exception as e:
            text = _first_line(e)
            if "incompatible function arguments" in text:
                text = f"wrong shape or type: {item!r}"
            raise ScenarioError(f"{source}: key '{_join(key, name)}': {text}") from None


def _is_number(text: str) -> bool:
    """Whether YAML text that was read as a string is a number (`1e-3`, `nan`)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _first_line(error: Exception) -> str:
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    return lines[0] if lines else type(error).__name__
