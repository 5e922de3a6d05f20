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
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TypeVar

from pydrake.common.yaml import yaml_dump, yaml_load_data, yaml_load_typed

from guidedarm.diagrams.scenario_schema import (
    CheckRawNode,
    FirstLine,
    ScenarioError,
)
from guidedarm.diagrams.station.hardware_config import RefuseReplacedDriverKeys
from guidedarm.diagrams.yaml_duplicates import FindDuplicateKey
from guidedarm.systems.config_checks import CheckConfig, FieldError
from guidedarm.systems.errors import ConfigurationError

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"

T = TypeVar("T")


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
                f"--set {key}: cannot parse value '{value}': {FirstLine(e)}"
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
        raise ScenarioError(f"{path}: malformed YAML: {FirstLine(e)}") from None
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


# Keys a task scenario no longer has: (the key that replaced it, why). A scenario has one
# `random_seed` from which every component draws its own stream (ToF noise, start pose,
# image noise); a component's own seed left in a scenario (e.g. `degradation.seed`) must
# agree with it. Path following has one `estimator`, read by every motion.
_ONE_SEED = "one random seed per scenario; every component draws its own stream from it"
REPLACED_KEYS = {
    "seed": ("random_seed", _ONE_SEED),
    "repeat_seed": ("repeat_random_seed", _ONE_SEED),
    "start.seed": ("random_seed", _ONE_SEED),
    "follower.estimator": ("estimator", "one hose estimator per run, read by every motion"),
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


def _refuse_driver_keys(raw: dict[str, Any], source: str) -> None:
    """An arm's `driver` or a ToF tool's `transport` under station.hardware is refused
    naming the YAML tag that replaced it (RefuseReplacedDriverKeys)."""
    station = raw.get("station")
    if isinstance(station, dict):
        try:
            RefuseReplacedDriverKeys(station.get("hardware"), "station.hardware")
        except FieldError as e:
            raise ScenarioError(f"{source}: {e}") from None


def load_typed(
    schema: type[T], raw: dict[str, Any], source: str, overridden: Iterable[str] = ()
) -> T:
    """Loads `raw` into the dataclass `schema` and checks it (CheckConfig), naming the
    offending key on failure, and `--set` instead of `source` for a key in (or under) one
    of the `overridden` dotted keys."""
    try:
        _refuse_replaced_keys(schema, raw, source)
        _refuse_moved_keys(raw, source)
        _refuse_driver_keys(raw, source)
        CheckRawNode(schema, raw, "", source)
        try:
            typed = yaml_load_typed(schema=schema, data=yaml_dump(raw))
        except Exception as e:
            raise ScenarioError(f"{source}: {FirstLine(e)}") from None
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
    for dotted, (replacement, why) in REPLACED_KEYS.items():
        node: Any = raw
        for part in dotted.split("."):
            node = node.get(part, _MISSING) if isinstance(node, dict) else _MISSING
        if node is not _MISSING:
            raise ScenarioError(f"{source}: key '{dotted}' was replaced by '{replacement}' ({why})")


_MISSING = object()
