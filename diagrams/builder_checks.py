"""Checks the public builders of diagrams/ make before they build anything.

CheckStationWiring: Drake finds a second connection into one input port, a port name the
station lacks, or a station left out of the builder only at Connect (a C++ "Failure at
...", or a RuntimeError listing every port), after the builder has already taken some of
the new systems: a half-wired builder the caller cannot use. CheckStationWiring refuses
all of these first, with one line naming the port.
"""

from __future__ import annotations

from collections.abc import Iterable

from pydrake.systems.framework import DiagramBuilder, System

from guidedarm.systems.config_checks import CheckInstance
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
