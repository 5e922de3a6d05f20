"""Generates the switch-panel model of Annusewicz-Mistal et al. from models/panel/panel.yaml.

Writes, next to the panel file: one texture per marker (`marker_<id>.png`, drawn by
cv2.aruco) with a textured square mesh (`marker_<id>.obj` + `.mtl`, map_Kd) that Drake's
VTK renderer shows, and `panel.sdf`: the plate (link `plate` = frame P), the markers on its
front face, one push switch per entry (link `<name>_cap` on the prismatic joint `<name>`
along z_P, latching, with damping: pressing it in past `on_travel_m` switches it on) and
a marker cover (visual only, on a prismatic joint along z_P, hidden behind the plate at
q = 0 and in front of the markers at q = COVER_CLOSED_M) used to study marker occlusion.

The tasks generate the model of their own panel file when they load it
(GeneratedPanelModel, WithGeneratedPanel), so a panel file is all a user writes. The
shipped models/panel/panel.sdf serves the model directives that name it
(models/directives/panel_scene.dmd.yaml); run
`.venv/bin/python -m guidedarm.diagrams.panel.panel_assets` after editing panel.yaml.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np
from pydrake.common.yaml import yaml_dump_typed
from pydrake.math import RollPitchYaw
from pydrake.multibody.parsing import FlattenModelDirectives, ModelDirectives
from pydrake.multibody.plant import MultibodyPlant

from guidedarm.diagrams.panel.panel_files import DEFAULT_PANEL_FILE, LoadPanelSpec
from guidedarm.diagrams.station.model_paths import MakeParser
from guidedarm.diagrams.station.scenario import StationScenario
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.markers.marker_pose_estimator_math import GetDictionary, PanelSpec

TEXTURE_CELL_PX = 100  # pixels per marker cell in the textures
PLATE_MARGIN_M = 0.06  # white plate around the markers and switches
PLATE_THICKNESS_M = 0.01
PLATE_FACE_Z_M = -0.0002  # the plate face sits just behind the marker quads (depth test)
COVER_HIDDEN_Z_M = -0.03
COVER_CLOSED_M = 0.033  # cover joint position that puts the cover 3 mm in front of the face
SWITCH_MASS_KG = 0.01
SWITCH_DAMPING_NS_PER_M = 20.0


def WritePanelAssets(panel_file: Path = DEFAULT_PANEL_FILE, out_dir: Path | None = None) -> list:
    """Writes the textures, meshes and panel.sdf for `panel_file`; returns the paths."""
    panel = LoadPanelSpec(panel_file)
    out_dir = Path(out_dir or Path(panel_file).parent)
    out_dir.mkdir(parents=True, exist_ok=True)
    dictionary = GetDictionary(panel.dictionary)
    written = []
    for marker in panel.markers:
        cells = dictionary.markerSize + 2
        image = cv2.aruco.generateImageMarker(dictionary, marker.id, cells * TEXTURE_CELL_PX, 1)
        stem = f"marker_{marker.id}"
        cv2.imwrite(str(out_dir / f"{stem}.png"), image)
        (out_dir / f"{stem}.mtl").write_text(
            f"newmtl {stem}\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nmap_Kd {stem}.png\n"
        )
        h = marker.size_m / 2
        # Texture v runs up the image as printed: (0, 0) is the marker's bottom-left corner.
        (out_dir / f"{stem}.obj").write_text(
            f"mtllib {stem}.mtl\no {stem}\n"
            f"v {-h} {-h} 0\nv {h} {-h} 0\nv {h} {h} 0\nv {-h} {h} 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
            f"usemtl {stem}\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
        )
        written += [out_dir / f"{stem}.{ext}" for ext in ("png", "mtl", "obj")]
    (out_dir / "panel.sdf").write_text(PanelSdf(panel))
    written.append(out_dir / "panel.sdf")
    return written


def GeneratedPanelModel(panel_file: str | Path) -> Path:
    """The panel.sdf generated from `panel_file` (with its marker textures and meshes) in a
    cache folder named by a hash of all it is generated from. It is written once, into a
    staging folder renamed into place, so parallel runs of one panel share it."""
    panel = LoadPanelSpec(panel_file)
    source = f"{TEXTURE_CELL_PX}\n{yaml_dump_typed(panel)}\n{PanelSdf(panel)}"
    key = hashlib.sha256(source.encode()).hexdigest()[:20]
    folder = Path(tempfile.gettempdir()) / "guidedarm-panels" / key
    if not (folder / "panel.sdf").is_file():
        folder.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=folder.parent))
        WritePanelAssets(panel_file, staging)
        try:
            staging.rename(folder)
        except OSError:  # another process put the same model there first
            shutil.rmtree(staging, ignore_errors=True)
    return folder / "panel.sdf"


def WithGeneratedPanel(
    station: StationScenario, panel_model: str, panel_file: str | Path
) -> StationScenario:
    """`station` with its model directives flattened and the model instance `panel_model`
    loaded from the model generated from `panel_file` (GeneratedPanelModel), so that the
    simulated scene shows the markers and switches the estimator and the sequencer read.
    ConfigurationError when the directives add no model of that name."""
    package_map = MakeParser(MultibodyPlant(0.0)).package_map()
    try:
        flat = FlattenModelDirectives(ModelDirectives(directives=station.directives), package_map)
    except Exception as e:
        raise ConfigurationError(f"station.directives: {str(e).splitlines()[0]}") from None
    models = [d.add_model for d in flat.directives if d.add_model]
    panels = [m for m in models if m.name == panel_model]
    if not panels:
        raise ConfigurationError(
            f"panel_model: no model instance '{panel_model}' in station.directives "
            f"(have {sorted(m.name for m in models)})"
        )
    panels[0].file = GeneratedPanelModel(panel_file).as_uri()
    return dataclasses.replace(station, directives=flat.directives)


def PanelSdf(panel: PanelSpec) -> str:
    """The SDFormat text of the panel model (see the module docstring)."""
    corners = [m.X_PM.GetDeterministicValue().translation()[:2] for m in panel.markers]
    half = [m.size_m / 2 for m in panel.markers]
    points = [c + s for c, s in zip(corners, half, strict=True)]
    points += [c - s for c, s in zip(corners, half, strict=True)]
    points += [np.array(s.position[:2]) for s in panel.switches]
    lo = np.min(points, axis=0) - PLATE_MARGIN_M
    hi = np.max(points, axis=0) + PLATE_MARGIN_M
    centre, size = (lo + hi) / 2, hi - lo
    plate_z = PLATE_FACE_Z_M - PLATE_THICKNESS_M / 2
    plate_box = (
        f"<pose>{centre[0]:.6g} {centre[1]:.6g} {plate_z:.6g} 0 0 0</pose>"
        f"<geometry><box><size>{size[0]:.6g} {size[1]:.6g} {PLATE_THICKNESS_M}</size></box>"
        "</geometry>"
    )
    markers = "".join(_MarkerVisual(m) for m in panel.markers)
    m_lo = np.min(points[: 2 * len(corners)], axis=0) - 0.005
    m_hi = np.max(points[: 2 * len(corners)], axis=0) + 0.005
    cover_c, cover_s = (m_lo + m_hi) / 2, m_hi - m_lo
    switches = "".join(_Switch(s) for s in panel.switches)
    return f"""<?xml version="1.0"?>
<!-- GENERATED by guidedarm.diagrams.panel.panel_assets from panel.yaml: do not edit by hand.
     Link `plate` is the panel frame P (centre of the left marker, x right, y up, z out of
     the panel face; the markers lie in z = 0, the plate face 0.2 mm behind).
     Masses are nominal (the plate is welded). -->
<sdf version="1.9">
  <model name="panel">
    <link name="plate">
      <inertial><mass>2.0</mass>
        <inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia></inertial>
      <visual name="plate">{plate_box}
        <material><diffuse>0.93 0.93 0.93 1</diffuse></material></visual>
      <collision name="plate">{plate_box}</collision>{markers}
    </link>{switches}
    <link name="cover">
      <pose>0 0 {COVER_HIDDEN_Z_M} 0 0 0</pose>
      <inertial><mass>0.05</mass>
        <inertia><ixx>1e-4</ixx><iyy>1e-4</iyy><izz>1e-4</izz></inertia></inertial>
      <visual name="cover">
        <pose>{cover_c[0]:.6g} {cover_c[1]:.6g} 0 0 0 0</pose>
        <geometry><box><size>{cover_s[0]:.6g} {cover_s[1]:.6g} 0.002</size></box></geometry>
        <material><diffuse>0.35 0.25 0.15 1</diffuse></material>
      </visual>
    </link>
    <joint name="cover_slide" type="prismatic">
      <parent>plate</parent><child>cover</child>
      <axis><xyz>0 0 1</xyz><limit><lower>0</lower><upper>{COVER_CLOSED_M}</upper></limit>
        <dynamics><damping>5.0</damping></dynamics></axis>
    </joint>
  </model>
</sdf>
"""


def _MarkerVisual(marker) -> str:
    X_PM = marker.X_PM.GetDeterministicValue()
    p = X_PM.translation()
    rpy = RollPitchYaw(X_PM.rotation()).vector()
    return f"""
      <visual name="marker_{marker.id}">
        <pose>{p[0]:.6g} {p[1]:.6g} {p[2]:.6g} {rpy[0]:.9g} {rpy[1]:.9g} {rpy[2]:.9g}</pose>
        <geometry><mesh><uri>marker_{marker.id}.obj</uri></mesh></geometry>
      </visual>"""


def _Switch(switch) -> str:
    x, y, face = switch.position
    cap = (
        f"<pose>0 0 {face / 2:.6g} 0 0 0</pose><geometry><cylinder>"
        f"<radius>{switch.radius_m}</radius><length>{face:.6g}</length></cylinder></geometry>"
    )
    return f"""
    <link name="{switch.name}_cap">
      <pose>{x:.6g} {y:.6g} 0 0 0 0</pose>
      <inertial><mass>{SWITCH_MASS_KG}</mass>
        <inertia><ixx>1e-6</ixx><iyy>1e-6</iyy><izz>1e-6</izz></inertia></inertial>
      <visual name="cap">{cap}
        <material><diffuse>0.75 0.1 0.1 1</diffuse></material></visual>
      <collision name="cap">{cap}</collision>
    </link>
    <joint name="{switch.name}" type="prismatic">
      <parent>plate</parent><child>{switch.name}_cap</child>
      <axis><xyz>0 0 1</xyz><limit><lower>{-switch.travel_m}</lower><upper>0</upper></limit>
        <dynamics><damping>{SWITCH_DAMPING_NS_PER_M}</damping></dynamics></axis>
    </joint>"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--panel", type=Path, default=DEFAULT_PANEL_FILE)
    parser.add_argument("--out", type=Path, default=None, help="default: beside the panel file")
    args = parser.parse_args()
    for path in WritePanelAssets(args.panel, args.out):
        print(path)


if __name__ == "__main__":
    main()
