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
# # 2. Your own hose on any arm: the UR10e
#
# Path following (Wawrzyniak et al.) reads the hose as a centerline CSV in the arm's base
# frame and keeps the tool inside the workspace walls, a box in the same frame. Any arm
# whose scenario names it can follow; here the UR10e holding the paper's gripper and
# six-sensor ToF tool (scenario `ur10e_path_following`). We write a hose, check the arm's
# reach and the tool's clearance from the walls, and follow it with both estimators,
# stop-and-go and continuous.

# %%
import html
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from IPython.display import display

from guidedarm.diagrams.run_context import MakeMeshcat, PrepareOutputDirectory, RunContext
from guidedarm.diagrams.station.station_plant import GetArmInstance
from guidedarm.diagrams.task_run import RunTask
from guidedarm.diagrams.tasks.path_following.setup import MakeSetup
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.hose_reach import CalcArmReach, ToolClearance
from guidedarm.systems.plant_frames import GetScopedFrame

os.chdir(tempfile.mkdtemp(prefix="guidedarm-tutorial-"))  # the files it writes go here

# %% [markdown]
# ## The hose
#
# A gentle S, 0.2 m long, 0.62-0.66 m in front of the UR10e's base and 0.11 m above its
# table (x, y, z in metres, the arm's base frame; a header row `x,y,z` or none).

# %%
x = np.linspace(-0.10, 0.10, 21)
hose = np.column_stack([x, -0.64 + 0.02 * np.sin(np.pi * x / 0.1), np.full_like(x, 0.11)])
np.savetxt("my_hose.csv", hose, delimiter=",", header="x,y,z", comments="", fmt="%.4f")

# %% [markdown]
# ## Reach, workspace and clearance
#
# `LoadScenario` reads a named scenario with `--set`-style overrides and checks every key;
# `MakeSetup` places the hose and solves the start pose. Before that it refuses a hose
# beyond the arm's reach or nearer a wall than the tool's clearance.

# %%
_, scenario, _ = LoadScenario("ur10e_path_following", ["path_csv=my_hose.csv"])
setup = MakeSetup(scenario)
solver = setup.solver
reach = CalcArmReach(solver.plant, GetArmInstance(solver.plant, "ur10e"), solver.frame, solver.p_FQ)
tool = GetScopedFrame(solver.plant, "tof_tool::tof_tool", "tool")
clearance = ToolClearance(solver.plant, tool)
farthest = np.linalg.norm(setup.centerline - reach.p_WS, axis=1).max()
print(f"workspace walls (m, base frame): {setup.workspace.Describe()}")
print(
    f"reach of the UR10e to the tool centre: {reach.reach:.3f} m; the hose reaches {farthest:.3f} m"
)
print(
    f"tool clearance: {1000 * clearance:.0f} mm; nearest wall: "
    f"{1000 * setup.workspace.Margin(setup.centerline_B):.0f} mm"
)
assert farthest < reach.reach and setup.workspace.Margin(setup.centerline_B) > clearance

# %% [markdown]
# The same hose moved 30 mm from the y wall is refused before anything moves, in one line:

# %%
np.savetxt("near_wall.csv", hose + [0.0, 0.64 - 0.87, 0.0], delimiter=",", fmt="%.4f")
try:
    MakeSetup(LoadScenario("ur10e_path_following", ["path_csv=near_wall.csv"])[1])
except ConfigurationError as refusal:
    print(refusal)
else:
    raise AssertionError("a hose inside the tool's clearance was accepted")

# %% [markdown]
# ## Following it
#
# Three runs: the paper's stop-and-go loop with its presence-only `grid` estimator and
# with `ranging` (which fits the hose centre to the six ranges), then `continuous`
# following. The stop-and-go runs use the kinematic executor (the arm posed where it is
# commanded, no servo lag) to keep this notebook quick; the continuous run goes through
# the full station and records a replay. Each run is what `guidedarm run
# ur10e_path_following --path-csv my_hose.csv --set ...` does. This hose bends at 51 mm
# radius, half the random hoses' smallest, for which the default continuous cruise (110
# mm/s) is chosen: at that cruise the tool strays up to 13.6 mm from this hose (3.9 mm
# on average), so the continuous run cruises at 50 mm/s.

# %%
runs = {
    "grid, stop-and-go": ["estimator=grid", "executor=kinematic"],
    "ranging, stop-and-go": ["estimator=ranging", "executor=kinematic"],
    "ranging, continuous": ["estimator=ranging", "motion=continuous", "continuous.speed=0.05"],
}
rows = {}
for name, overrides in runs.items():
    task, scenario, _ = LoadScenario("ur10e_path_following", ["path_csv=my_hose.csv", *overrides])
    out_dir = PrepareOutputDirectory(Path("runs") / name.replace(", ", "_"))
    context = RunContext(out_dir=out_dir, quiet=True)
    if "continuous" in name:
        context.meshcat = MakeMeshcat()
    rows[name] = RunTask(task, scenario, context)
    replay = context.out_dir / "replay.html"

table = pd.DataFrame(rows).T[
    [
        "success",
        "coverage",
        "tracking_error_mean_mm",
        "tracking_error_max_mm",
        "detected_path_error_mean_mm",
        "average_speed_mm_s",
        "collisions",
    ]
]
display(table)
assert table["success"].all() and (table["collisions"] == 0).all()
assert (
    table.loc["ranging, continuous", "average_speed_mm_s"]
    > 1.5 * table.loc["ranging, stop-and-go", "average_speed_mm_s"]
)

# %% [markdown]
# The continuous run's replay: the ToF cones and hits, the detected path and the tool
# centre's trail are drawn under `/overlays/` (open the Meshcat controls to hide them).

# %%
iframe = f'<iframe srcdoc="{html.escape(replay.read_text())}" width="100%" height="450"></iframe>'
display({"text/html": iframe}, raw=True)
