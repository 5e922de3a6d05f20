# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 3. Your own marker panel and camera, end to end
#
# The switch-panel task (Annusewicz-Mistal et al.) reads one panel file: the ArUco
# dictionary, each marker's id, size and pose in the panel frame P, and the switches.
# The same file drives the estimator and the simulated scene: the panel's model and its
# marker textures are generated from it when the task loads. Here: 40 mm markers of the
# 4 x 4 dictionary, switches with names of our own, and a 1280 x 720 camera.

# %%
import html
import json
import os
import tempfile
from pathlib import Path

from IPython.display import Image, display

from guidedarm.diagrams.cli.main import main

os.chdir(tempfile.mkdtemp(prefix="guidedarm-tutorial-"))  # the files it writes go here

# %% [markdown]
# ## The panel file
#
# P is the frame of the first marker (x right, y up as printed, z out of the panel);
# `X_PM` places each marker in P (m). A switch's `position` is its cap's face centre in P.

# %%
Path("my_panel.yaml").write_text("""\
dictionary: DICT_4X4_50
markers:
- {id: 3, size_m: 0.04, X_PM: {translation: [0.0, 0.0, 0.0]}}
- {id: 11, size_m: 0.04, X_PM: {translation: [0.10, 0.0, 0.0]}}
switches:
- {name: left, position: [0.02, -0.05, 0.012]}
- {name: middle, position: [0.05, -0.05, 0.012]}
- {name: right, position: [0.08, -0.05, 0.012]}
""")

# %% [markdown]
# ## Your camera
#
# The gripper camera is a Drake `CameraConfig` of the scenario's station
# (`station.cameras.camera`): here 1280 x 720 px with the C920's field of view
# (fx = fy = 906.8 px). The estimator takes its intrinsics from the same config, and
# `supersampling=1` renders it once per pixel (the default 3 is closer to a real sensor's
# pixel integration, and slower).

# %%
camera = [
    "station.cameras.camera.width=1280",
    "station.cameras.camera.height=720",
    "station.cameras.camera.focal=!FocalLength {x: 906.8, y: 906.8}",
    "supersampling=1",
]


def Run(*args: str) -> dict:
    """`guidedarm run ARGS` in this process; returns its summary.json."""
    out = Path("runs") / args[0]
    code = main(["run", *args, "--out", str(out)])
    summary = json.loads((out / "summary.json").read_text())
    assert code == 0, summary["failure"]
    return summary


# %% [markdown]
# ## One view of the panel
#
# `marker_view` renders the panel from a free camera 0.25 m away, turned 15 deg about
# P's y axis, estimates the pose (OpenCV ArUco + PnP) and compares it with the truth.

# %%
view = Run(
    "marker_view",
    "--set",
    "panel_file=my_panel.yaml",
    "--set",
    "distance_m=0.25",
    "--set",
    "angle_deg=15",
    "--set",
    "camera={width: 1280, height: 720, focal: !FocalLength {x: 906.8, y: 906.8}}",
    "--set",
    "supersampling=1",
)
print(
    f"markers {view['ids']}: distance error {view['abs_error_mm']:.3f} mm, "
    f"rotation error {view['rotation_error_deg']:.3f} deg"
)
assert view["ids"] == [3, 11] and view["abs_error_mm"] < 1.0
display(Image(filename="runs/marker_view/view.png", width=640))

# %% [markdown]
# ## Pressing a switch
#
# `panel_operation`: from a random start the rover arm measures the panel with its
# camera, moves to the base point 170 mm in front of it, then to the switch point, presses
# switch 3 (`right`) and retracts. The switch caps are prismatic joints moved by contact,
# so the press is observed in the simulation, not assumed.

# %%
args = ["panel_operation", "--set", "panel_file=my_panel.yaml", "--set", "switch=3"]
for key in camera:
    args += ["--set", key]
press = Run(*args)
print(
    f"switch pressed: {press['switch_pressed']}; press error (mm, panel frame): "
    f"{press['press_error_mm']}"
)
assert press["switch_pressed"] == 3 and max(press["press_error_mm"].values()) < 0.5

# %% [markdown]
# The run's replay: the camera's viewing pyramid, the estimated and the true panel frame
# and the target switch are drawn under `/overlays/panel`.

# %%
page = Path("runs/panel_operation/replay.html").read_text()
iframe = f'<iframe srcdoc="{html.escape(page)}" width="100%" height="450"></iframe>'
display({"text/html": iframe}, raw=True)
