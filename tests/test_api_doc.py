"""docs/api.md documents every LeafSystem of guidedarm.systems (the only package defining
LeafSystems, overlays included) with each of its ports.

The ports are read from the source (every Declare*Port call of the class, also those
declared through a helper function such as DeclareGridOutputs, and names iterated in a
literal tuple), so conditional ports (PanelOperation's planner ports, AccelerationPlanner's
`task`) count too; the reading is checked against built systems. A port name the reader
cannot resolve fails the test: declare ports with literal names.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import re
import textwrap

import pytest
from conftest import REPO
from pydrake.systems.framework import LeafSystem

import guidedarm.systems as systems_package

DECLARE = re.compile(r"Declare(Vector|Abstract)(Input|Output)Port$")


def LeafSystemClasses() -> dict[str, type]:
    """Every LeafSystem subclass defined in a module of guidedarm.systems, by name."""
    classes = {}
    for info in pkgutil.walk_packages(systems_package.__path__, "guidedarm.systems."):
        module = importlib.import_module(info.name)
        for name, cls in vars(module).items():
            if (
                inspect.isclass(cls)
                and issubclass(cls, LeafSystem)
                and cls is not LeafSystem
                and cls.__module__ == module.__name__
            ):
                classes[name] = cls
    return classes


def DeclaredPorts(function_or_class, seen: set | None = None) -> set[str]:
    """Names of the ports the source of a class (or function) declares, through the
    functions of guidedarm.systems it calls (each read once: some call themselves)."""
    seen = set() if seen is None else seen
    seen.add(function_or_class)
    source = textwrap.dedent(inspect.getsource(function_or_class))
    tree = ast.parse(source)
    module = inspect.getmodule(function_or_class)
    loops = {}  # loop variable -> the string constants it takes
    for node in ast.walk(tree):
        if isinstance(node, ast.For) and isinstance(node.iter, ast.Tuple | ast.List):
            targets = node.target.elts if isinstance(node.target, ast.Tuple) else [node.target]
            for i, target in enumerate(targets):
                values = []
                for item in node.iter.elts:
                    item = item.elts[i] if isinstance(item, ast.Tuple) else item
                    if isinstance(item, ast.Constant) and isinstance(item.value, str):
                        values.append(item.value)
                if isinstance(target, ast.Name) and values:
                    loops[target.id] = values
    names = set()
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
        if DECLARE.match(called):
            first = node.args[0] if node.args else None
            if isinstance(first, ast.Constant) and isinstance(first.value, str):
                names.add(first.value)
            elif isinstance(first, ast.Name) and first.id in loops:
                names.update(loops[first.id])
            else:
                raise AssertionError(
                    f"{function_or_class.__qualname__}: cannot read the port name of "
                    f"{ast.unparse(node)[:80]}; use a literal"
                )
        elif isinstance(func, ast.Name):  # a helper that declares ports for the system
            helper = getattr(module, func.id, None)
            if (
                inspect.isfunction(helper)
                and helper.__module__.startswith("guidedarm.systems")
                and helper not in seen
            ):
                names.update(DeclaredPorts(helper, seen))
    return names


def ApiSections() -> dict[str, str]:
    """docs/api.md split at its `### Name` headings."""
    text = (REPO / "docs" / "api.md").read_text()
    parts = re.split(r"^### +`?(\w+)`?.*$", text, flags=re.MULTILINE)
    return dict(zip(parts[1::2], parts[2::2], strict=True))


@pytest.mark.parametrize("name", sorted(LeafSystemClasses()))
def test_every_leaf_system_and_port_is_in_the_api_doc(name):
    sections = ApiSections()
    assert name in sections, f"docs/api.md has no '### {name}' section"
    ports = DeclaredPorts(LeafSystemClasses()[name])
    # A system without ports (SeeThroughGeometry) says so, so that a reading that finds
    # none by mistake still fails.
    assert ports or "no ports" in sections[name], f"{name}: no ports found"
    missing = sorted(p for p in ports if f"`{p}`" not in sections[name])
    assert missing == [], f"docs/api.md, section {name}: ports {missing} are not listed"


def test_the_port_reader_matches_built_systems():
    """Static reading = the ports of real instances (all variants of conditional ones)."""
    from guidedarm.diagrams.station.station import MakeStation
    from guidedarm.diagrams.tasks.registry import LoadScenario
    from guidedarm.systems.markers.image_degradation import DegradationConfig, ImageDegradation
    from guidedarm.systems.markers.marker_pose_estimator import MarkerPoseEstimator
    from guidedarm.systems.markers.marker_pose_estimator_math import (
        CameraIntrinsics,
        MarkerPoseSolver,
        MarkerSpec,
        PanelSpec,
    )

    task, scenario, _ = LoadScenario("path_following", [])
    station = MakeStation(task.Station(scenario))
    panel = PanelSpec(markers=[MarkerSpec(id=7)])
    built = [
        station.GetSubsystemByName("tof.sensor"),  # ToFToolSensor
        ImageDegradation(DegradationConfig()),
        MarkerPoseEstimator(MarkerPoseSolver(CameraIntrinsics(), panel)),
    ]
    for system in built:
        ports = {system.get_input_port(i).get_name() for i in range(system.num_input_ports())} | {
            system.get_output_port(i).get_name() for i in range(system.num_output_ports())
        }
        assert DeclaredPorts(type(system)) == ports, type(system).__name__


BUILDER = re.compile(r"(Make|Add|Start|Save)[A-Z]\w*$")


def _DiagramModules():
    """The modules a user builds diagrams from: guidedarm.diagrams without the CLI and the
    campaign engine (their functions are commands, not builders)."""
    import guidedarm.diagrams as diagrams_package

    for info in pkgutil.walk_packages(diagrams_package.__path__, "guidedarm.diagrams."):
        if not info.name.startswith(("guidedarm.diagrams.cli", "guidedarm.diagrams.campaigns")):
            yield importlib.import_module(info.name)


def test_every_public_builder_is_in_the_api_doc():
    text = (REPO / "docs" / "api.md").read_text()
    builders = {
        name
        for module in _DiagramModules()
        for name, function in vars(module).items()
        if inspect.isfunction(function)
        and function.__module__ == module.__name__
        and BUILDER.match(name)
    }
    assert {"AddWaypointOverlays", "SaveReplay", "MakeStation"} <= builders
    listed = set(re.findall(r"`(\w+)[`(]", text)) | set(re.findall(r"^### .*", text, re.M))
    assert (
        sorted(b for b in builders if b not in listed and not re.search(rf"### .*\b{b}\b", text))
        == []
    )


def test_leaf_systems_live_only_under_systems():
    """No module of guidedarm.diagrams (builders, tasks, commands) defines a LeafSystem;
    the overlays are among the systems the first test reads."""
    import guidedarm.diagrams as diagrams_package

    defined = sorted(
        f"{info.name}.{name}"
        for info in pkgutil.walk_packages(diagrams_package.__path__, "guidedarm.diagrams.")
        for name, cls in vars(importlib.import_module(info.name)).items()
        if inspect.isclass(cls) and issubclass(cls, LeafSystem) and cls.__module__ == info.name
    )
    assert defined == []
    assert {"FrameTrailOverlay", "ToFToolOverlay", "SeeThroughGeometry"} <= set(LeafSystemClasses())
