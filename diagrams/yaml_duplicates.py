"""Keys given twice in one YAML mapping: YAML readers (PyYAML, and Drake's on top of it)
keep the last value without a word; scenario_loading.RefuseDuplicateKeys refuses them."""

from __future__ import annotations

from typing import Any

import yaml

from guidedarm.diagrams.scenario_schema import JoinKey


def FindDuplicateKey(text: str) -> tuple[str, list[int]] | None:
    """The dotted path and 1-based lines of the first key given twice in one mapping of
    the YAML `text` (a mapping's own keys before those of its values), or None. The text
    must parse."""
    return _FindInNode(yaml.compose(text, Loader=yaml.SafeLoader), "", set())


def _FindInNode(node: Any, key: str, seen: set[int]) -> tuple[str, list[int]] | None:
    """The dotted path and lines of the first key given twice in one mapping under the
    composed YAML `node` (a mapping's own keys before those of its values), or None."""
    if node is None or id(node) in seen:  # an alias of a node already walked
        return None
    seen.add(id(node))
    if isinstance(node, yaml.SequenceNode):
        children = [(f"{key}[{i}]", item) for i, item in enumerate(node.value)]
    elif isinstance(node, yaml.MappingNode):
        where: dict[str, list[int]] = {}
        children = []
        for name_node, value in node.value:
            name = str(name_node.value) if isinstance(name_node, yaml.ScalarNode) else ""
            if name_node.tag == "tag:yaml.org,2002:merge":
                continue
            where.setdefault(name, []).append(name_node.start_mark.line + 1)
            children.append((JoinKey(key, name), value))
        for name, found in where.items():
            if len(found) > 1:
                return JoinKey(key, name), found
    else:
        return None
    for child_key, child in children:
        duplicate = _FindInNode(child, child_key, seen)
        if duplicate is not None:
            return duplicate
    return None
