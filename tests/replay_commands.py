"""Reads what a Meshcat replay page (Meshcat.StaticHtml) shows: the recorded commands,
embedded as base64 msgpack in `fetch("data:...")` calls, and the recorded animation."""

from __future__ import annotations

import base64
import re
from pathlib import Path
from typing import Any

import msgpack
import numpy as np

_EMBEDDED = re.compile(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)")


def ReplayCommands(page: str | Path) -> list[dict[str, Any]]:
    """Every command of the page, decoded, in page order."""
    text = Path(page).read_text()
    return [
        msgpack.unpackb(base64.b64decode(m.group(1)), raw=False, strict_map_key=False)
        for m in _EMBEDDED.finditer(text)
    ]


class Replay:
    """The scene of a replay page: objects, transforms and properties by path, and the
    animation's tracks by (path, property)."""

    def __init__(self, page: str | Path) -> None:
        self.commands = ReplayCommands(page)
        self.objects: dict[str, dict] = {}
        self.transforms: dict[str, list[float]] = {}
        self.properties: dict[tuple[str, str], Any] = {}
        self.tracks: dict[tuple[str, str], dict] = {}
        self.fps = 0.0
        for c in self.commands:
            kind = c["type"]
            if kind == "set_object":
                self.objects[c["path"]] = c["object"]
            elif kind == "set_transform":
                self.transforms[c["path"]] = c["matrix"]
            elif kind == "set_property":
                self.properties[(c["path"], c["property"])] = c["value"]
            elif kind == "set_animation":
                for animation in c["animations"]:
                    clip = animation["clip"]
                    self.fps = clip["fps"]
                    for track in clip["tracks"]:
                        name = track["name"].lstrip(".")
                        self.tracks[(animation["path"], name)] = track

    def Paths(self, prefix: str) -> list[str]:
        """Paths of objects under `prefix`."""
        return sorted(p for p in self.objects if p.startswith(prefix))

    def Translation(self, path: str) -> list[float]:
        """The translation at `path` that the page shows at the end: the last key of its
        recorded `position` track, else the (column-major 4 x 4) transform set there (a
        run without a live page records poses into the animation only)."""
        if (path, "position") in self.tracks:
            return list(self.tracks[(path, "position")]["keys"][-1]["value"])
        return self.transforms[path][12:15]

    def Keyframes(self, path: str, name: str) -> list[tuple[float, Any]]:
        """(time s, value) of the recorded track of property `name` at `path`."""
        track = self.tracks[(path, name)]
        return [(k["time"] / self.fps, k["value"]) for k in track["keys"]]


def Vertices(meshcat_object: dict) -> np.ndarray:
    """The vertices (N x 3) of a line or line-segments object (float32 typed array,
    msgpack extension 23)."""
    array = meshcat_object["geometries"][0]["data"]["attributes"]["position"]["array"]
    data = array.data if isinstance(array, msgpack.ExtType) else bytes(array)
    return np.frombuffer(data, "<f4").reshape(-1, 3).astype(float)
