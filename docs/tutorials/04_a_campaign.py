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
# # 4. A campaign, and its results with pandas
#
# `guidedarm sweep` runs many variants of one scenario on Dask (local worker processes,
# or a cluster given by `--scheduler`) into one table, `results.csv`, a row per job. Here:
# the marker estimator's distance error at two camera distances, without and with
# image noise, each with two noise seeds: eight one-image jobs.

# %%
import html
import os
import tempfile
from pathlib import Path

import pandas as pd
from IPython.display import display

from guidedarm.diagrams.campaigns.report import MeanInterval
from guidedarm.diagrams.cli.main import main

os.chdir(tempfile.mkdtemp(prefix="guidedarm-tutorial-"))  # the files it writes go here

# %% [markdown]
# ## The campaign file
#
# `scenario` and `set` say what every job runs; `grid` axes are crossed; `repeat` runs
# each combination with several values of a seed key; `metrics` are the summary figures
# to collect (`guidedarm describe marker_view --metrics` lists them with their units).

# %%
Path("distance_noise.yaml").write_text("""\
description: "distance error of the marker estimator, with and without image noise"
scenario: marker_view
set: {supersampling: 1}
grid:
  distance_m: [0.25, 0.4]
  degradation.noise_std: [0.0, 6.0]
repeat: {key: random_seed, count: 2}
metrics: [abs_error_mm, rotation_error_deg, reprojection_error_px]
""")

# %% [markdown]
# ## Running it
#
# One local worker process keeps this notebook light; `--workers N` or `--scheduler
# tcp://HOST:8786` spread the jobs. A rerun into the same folder runs only what is missing.

# %%
code = main(["sweep", "distance_noise.yaml", "--out", "campaign", "--workers", "1"])
assert code == 0

# %% [markdown]
# ## The results with pandas
#
# One row per job: its id, the axes' values, `success`, `failure` and the metrics.

# %%
results = pd.read_csv("campaign/results.csv")
display(results.head())
assert len(results) == 8 and results["success"].all()

# %% [markdown]
# Mean and a 95 % interval of the mean (Student's t over the repeats; `MeanInterval`, the
# report's own) of the distance error per distance and noise level:

# %%
grouped = results.groupby(["distance_m", "degradation.noise_std"])["abs_error_mm"]
table = grouped.apply(lambda errors: pd.Series(MeanInterval(list(errors)), ["mean", "ci95", "n"]))
table = table.unstack()
display(table.round(4))
noisy = results[results["degradation.noise_std"] > 0]["abs_error_mm"]
print(
    f"largest distance error: {results['abs_error_mm'].max():.3f} mm "
    f"(with noise {noisy.max():.3f} mm)"
)
assert results["abs_error_mm"].max() < 2.0

# %% [markdown]
# Without noise a render is exact, so both seeds give the same error (standard deviation
# 0); with noise the seeds differ. The same as a pivot table, one column per noise level:

# %%
display(
    results.pivot_table(
        index="distance_m", columns="degradation.noise_std", values="abs_error_mm", aggfunc="mean"
    ).round(4)
)

# %% [markdown]
# `campaign/report.html`, written by the sweep, plots every metric by each axis (a box
# per axis value, the jobs as points coloured by another axis) with a table of means and
# 95 % intervals:

# %%
page = Path("campaign/report.html").read_text()
iframe = f'<iframe srcdoc="{html.escape(page)}" width="100%" height="500"></iframe>'
display({"text/html": iframe}, raw=True)
