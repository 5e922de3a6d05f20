"""Where the project's models live, and a Parser that resolves `package://guidedarm/...`."""

from __future__ import annotations

from pathlib import Path

from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

MODELS_DIR = Path(__file__).resolve().parents[2] / "models"
PACKAGE_XML = MODELS_DIR / "package.xml"


def MakeParser(plant: MultibodyPlant) -> Parser:
    """A Parser for `plant` that knows only this repository's `guidedarm` package."""
    parser = Parser(plant)
    package_map = parser.package_map()
    if not package_map.Contains("guidedarm"):
        package_map.AddPackageXml(str(PACKAGE_XML))
    return parser
