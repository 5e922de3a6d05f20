"""`guidedarm describe TASK|SCENARIO`: every key of a task's scenario schema, nested.

Each key is printed with its type, its default (or, for a named scenario or scenario file,
the scenario's value with `--set` overrides applied) and one line of documentation:

- a field of one of our dataclasses: its `name: text` entry in the dataclass docstring
  (`a, b: text` documents both; an entry runs to the next entry or a blank line); a field
  holding a dataclass or Drake struct that has no entry takes its type's first docstring
  line; `task` is the registry's (every scenario schema has it);
- a field of a Drake struct (MultibodyPlantConfig, CameraConfig, Transform, ...): the
  first sentence of pydrake's documentation of that field, or of FALLBACK_DOCS where
  pydrake has none.

Mappings keyed by name (`station.arms`, `station.cameras`, ...) list each entry of the
scenario, or `<name>` with the entry type's defaults when the mapping is empty.

`--metrics` lists instead every key of the task's summary.json with its unit and meaning
(TaskDefinition.metrics, RUN_METRICS and SUMMARY_KEYS), and for an accuracy metric
whether it is measured on the true cell or from what the controller believes
(TaskDefinition.MetricSource).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import inspect
import os
import re
import sys
import types
import typing
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.common.schema import Rotation
from pydrake.geometry import Rgba

from guidedarm.diagrams.scenario_loading import AddOverridesArgument, list_named_scenarios
from guidedarm.diagrams.tasks.registry import (
    SUMMARY_KEYS,
    GetTask,
    LoadScenario,
    TaskDefinition,
    TaskNames,
)
from guidedarm.systems.errors import ConfigurationError

TASK_DOC = "the task this scenario runs (diagrams/tasks/<task>/)"

# Drake structs shown as one value, not expanded into their fields.
LEAF_STRUCTS = (Rgba, Rotation)

# Fields of Drake structs that pydrake leaves undocumented, keyed `Struct.field`.
FALLBACK_DOCS = {
    "SimulatorConfig.integration_scheme": "the integrator, e.g. runge_kutta3, implicit_euler",
    "SimulatorConfig.max_step_size": "largest integration step (s)",
    "SimulatorConfig.accuracy": "target accuracy of error-controlled integrators",
    "SimulatorConfig.use_error_control": "whether the integrator adapts its step to accuracy",
    "SimulatorConfig.target_realtime_rate": "pace the simulation at this multiple of real "
    "time (0: as fast as possible)",
    "Transform.base_frame": "the frame the pose is relative to (scoped name; empty: world)",
    "Transform.translation": "position of the frame's origin in the base frame (m)",
}


# Column widths are capped (key, type, value); a longer cell pushes the rest of its row.
WIDTHS = (("key", 48), ("type", 28), ("value", 24))


@dataclass
class KeyDoc:
    """One row: dotted key, type, value (default or the scenario's), one doc line."""

    key: str
    type: str
    value: str
    doc: str


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "describe", help="list every scenario key of a task with its type, default and doc"
    )
    parser.add_argument(
        "target",
        help="a task name, a named scenario (which wins over a task of the same name) or a "
        "scenario YAML file",
    )
    parser.add_argument(
        "--defaults",
        action="store_true",
        help="show the schema's defaults instead of the scenario's values",
    )
    parser.add_argument(
        "--metrics",
        action="store_true",
        help="list every key of the task's summary.json with its unit and meaning instead",
    )
    AddOverridesArgument(parser, "override a scenario key before describing it")
    parser.set_defaults(func=describe_command)


def describe_command(args: argparse.Namespace) -> int:
    tasks = TaskNames()
    scenarios = list_named_scenarios()
    task_only = args.target in tasks and args.target not in scenarios
    if args.overrides and (args.defaults or args.metrics or task_only):
        # The schema's defaults and the metrics do not read a scenario's --set values.
        shown = "--defaults" if args.defaults else f"task '{args.target}' (its defaults)"
        if args.metrics:
            raise ConfigurationError("--set has no effect with --metrics (a task's metrics)")
        raise ConfigurationError(f"--set has no effect with {shown}: describe a scenario")
    if task_only:
        task, scenario, name = GetTask(args.target), None, None
    elif args.target not in scenarios and not args.target.endswith((".yaml", ".yml")):
        raise ConfigurationError(
            f"unknown task or scenario '{args.target}' (tasks: {', '.join(tasks)}; "
            f"scenarios: {', '.join(scenarios)})"
        )
    else:
        task, scenario, name = LoadScenario(args.target, args.overrides)
    if args.metrics:
        return _Print(MetricRows(task))
    if scenario is None or args.defaults:
        scenario = task.scenario_type()
        print(f"task {task.name} ({task.description}): defaults of {type(scenario).__name__}")
    else:
        print(f"scenario {name} (task {task.name}): its values, {type(scenario).__name__}")
    rows = DescribeScenario(scenario)
    widths = [min(max(len(getattr(r, a)) for r in rows), w) for a, w in WIDTHS]
    lines = [_Row(["key", "type", "value", "doc"], widths)]
    lines += [_Row([r.key, r.type, r.value, r.doc], widths) for r in rows]
    return _Print(lines)


def MetricRows(task: TaskDefinition) -> list[str]:
    """The lines of `describe --metrics`: every summary.json key of the task (a list's
    elements as `name.#`) with its unit and meaning."""
    docs = {**SUMMARY_KEYS, **task.MetricDocs()}
    width = max(len(k) for k in docs)
    unit_width = max(len(u) for u, _ in docs.values())
    lines = [f"summary.json of task {task.name} ({task.description})"]
    lines.append(f"{'key':{width}}  {'unit':{unit_width}}  meaning")
    for key, (unit, doc) in docs.items():
        source = task.MetricSource(key) if key in task.metrics else ""
        lines.append(
            f"{key:{width}}  {unit:{unit_width}}  {doc}" + (f" [{source}]" if source else "")
        )
    return lines


def _Print(lines: list[str]) -> int:
    try:
        print("\n".join(lines), flush=True)
    except BrokenPipeError:
        # The reader stopped early (`| head`): not an error. Later flushes go nowhere.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def _Row(cells: list[str], widths: list[int]) -> str:
    return "  ".join(f"{c:{w}}" for c, w in zip(cells, [*widths, 0], strict=True)).rstrip()


def DescribeScenario(scenario: Any) -> list[KeyDoc]:
    """The rows of every key of a scenario dataclass instance, depth first."""
    rows: list[KeyDoc] = []
    _DescribeFields(type(scenario), scenario, "", rows)
    return rows


def FieldDocs(cls: type) -> dict[str, str]:
    """The `name: text` entries of a dataclass docstring, by field name (see the module
    docstring, or of a base class's for an inherited field); fields without an entry are
    absent."""
    docs: dict[str, str] = {}
    for klass in cls.__mro__:
        if dataclasses.is_dataclass(klass):
            for name, doc in _FieldDocs(klass):
                docs.setdefault(name, doc)
    return docs


@functools.cache
def _FieldDocs(cls: type) -> tuple[tuple[str, str], ...]:
    text = inspect.getdoc(cls) or ""
    fields = {f.name for f in dataclasses.fields(cls)}
    entry = re.compile(
        r"(?<![\w.`'-])((?:`?\w+`?)(?:\s*,\s*`?\w+`?)*(?:,?\s+and\s+`?\w+`?)?)\s*:(?=\s)"
    )
    starts = []
    for match in entry.finditer(text):
        names = [n.strip("` ") for n in re.split(r",|\band\b", match.group(1))]
        if names and all(n in fields for n in names):
            starts.append((match.start(), match.end(), names))
    docs = {}
    for i, (_, end, names) in enumerate(starts):
        stop = starts[i + 1][0] if i + 1 < len(starts) else len(text)
        body = re.split(r"\n\s*\n", text[end:stop])[0]
        line = " ".join(body.split()).rstrip(";,")
        for name in names:
            docs.setdefault(name, line)
    return tuple(docs.items())


def _DescribeFields(cls: type, value: Any, prefix: str, rows: list[KeyDoc]) -> None:
    docs = FieldDocs(cls)
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        doc = docs.get(f.name) or (TASK_DOC if f.name == "task" and not prefix else "")
        _Describe(hints[f.name], getattr(value, f.name), prefix + f.name, doc, rows)


def _DescribeStruct(cls: type, value: Any, prefix: str, rows: list[KeyDoc]) -> None:
    for f in cls.__fields__:
        doc = _FirstSentence(getattr(cls, f.name).__doc__)
        doc = doc or FALLBACK_DOCS.get(f"{cls.__name__}.{f.name}", "")
        _Describe(f.type, getattr(value, f.name), f"{prefix}{f.name}", doc, rows)


def _Describe(schema: Any, value: Any, key: str, doc: str, rows: list[KeyDoc]) -> None:
    """Adds the row of `key` (and of its nested keys) to rows."""
    variants = _Variants(schema)
    if variants:
        # A tagged union: the entry's own type, or each type for an empty mapping.
        for cls in [type(value)] if value is not None else variants:
            shown = value if value is not None else cls()
            rows.append(KeyDoc(key, f"!{cls.__name__}", "", doc or _FirstSentence(cls.__doc__)))
            _DescribeFields(cls, shown, f"{key}.", rows)
        return
    nested = _NestedType(schema)
    if nested is not None and not doc:
        doc = _FirstSentence(nested.__doc__)
    origin = typing.get_origin(schema)
    if origin is dict:
        (item_schema,) = typing.get_args(schema)[1:]
        count = f"{len(value)} entr{'y' if len(value) == 1 else 'ies'}"
        rows.append(KeyDoc(key, _TypeName(schema), f"{{{count}}}", doc))
        entries = value.items() if value else [("<name>", _Default(item_schema))]
        for name, item in entries:
            _Describe(item_schema, item, f"{key}.{name}", f"one entry of {key}", rows)
        return
    if nested is None:
        rows.append(KeyDoc(key, _TypeName(schema), _FormatValue(value), doc))
        return
    rows.append(KeyDoc(key, _TypeName(schema), "null" if value is None else "", doc))
    shown = value if value is not None else _Default(nested)
    if dataclasses.is_dataclass(nested):
        _DescribeFields(nested, shown, f"{key}.", rows)
    else:
        _DescribeStruct(nested, shown, f"{key}.", rows)


def _NestedType(schema: Any) -> type | None:
    """The dataclass or expandable Drake struct of a field (also `X | None`), else None."""
    members = [m for m in _UnionMembers(schema) if m is not type(None)]
    if len(members) != 1:
        return None
    (member,) = members
    if dataclasses.is_dataclass(member):
        return member
    if hasattr(member, "__fields__") and member not in LEAF_STRUCTS:
        return member
    return None


def _Variants(schema: Any) -> list[type]:
    """The dataclasses of a tagged union (a Union of two or more dataclasses), else []."""
    members = [m for m in _UnionMembers(schema) if m is not type(None)]
    return members if len(members) > 1 and all(map(dataclasses.is_dataclass, members)) else []


def _UnionMembers(schema: Any) -> tuple:
    if typing.get_origin(schema) in (typing.Union, types.UnionType):
        return typing.get_args(schema)
    return (schema,)


def _Default(schema: Any) -> Any:
    if _Variants(schema):
        return None  # _Describe lists each type of the union
    nested = _NestedType(schema)
    return nested() if nested is not None else schema()


def _TypeName(schema: Any) -> str:
    origin = typing.get_origin(schema)
    if origin is typing.Literal:
        return " | ".join(repr(a) for a in typing.get_args(schema))
    if origin in (typing.Union, types.UnionType):
        names = [_TypeName(m) for m in typing.get_args(schema)]
        return " | ".join(dict.fromkeys(n for n in names if not n.startswith("_")))
    if origin is not None:
        return f"{origin.__name__}[{', '.join(_TypeName(a) for a in typing.get_args(schema))}]"
    if schema is type(None):
        return "None"
    if schema is np.ndarray:
        return "list[float]"
    # Drake's template instantiations carry their parameters in mathematical letters.
    return re.split(r"[\U0001D400-\U0001D7FF]", getattr(schema, "__name__", str(schema)))[0]


def _FormatValue(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return value if value else "''"
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, list):
        if all(isinstance(v, int | float | str | list) for v in value):
            return str(value).replace("'", "")
        return "[" + ", ".join(_ShortStruct(v) for v in value) + "]"
    return repr(value)


def _ShortStruct(value: Any) -> str:
    """A Drake struct (e.g. a ModelDirective) by its fields that are set, nested."""
    if not hasattr(value, "__fields__") or isinstance(value, LEAF_STRUCTS):
        return _FormatValue(value)
    fields = [(f.name, getattr(value, f.name)) for f in value.__fields__]
    parts = [f"{name}: {_ShortStruct(item)}" for name, item in fields if item is not None]
    return "{" + ", ".join(parts) + "}"


def _FirstSentence(text: str | None) -> str:
    """The first sentence of a docstring, on one line, without Doxygen's markup."""
    if not text:
        return ""
    paragraph = re.split(r"\n\s*\n", text.strip())[0]
    line = " ".join(paragraph.split()).replace("%", "").replace("∷", "::")
    return re.split(r"(?<=[a-z0-9)])\.\s", line)[0].rstrip(".")
