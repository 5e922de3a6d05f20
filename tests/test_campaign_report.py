"""The campaign report compares: per metric, a box plot per value of one axis with the jobs
coloured by another, and a table of means with 95 % intervals per axis value."""

from __future__ import annotations

import math
import re

import pytest

from guidedarm.diagrams.campaigns.campaign import CampaignConfig
from guidedarm.diagrams.campaigns.report import MeanInterval, WriteReport
from guidedarm.diagrams.campaigns.results import ResultsTable
from guidedarm.diagrams.tasks.registry import GetTask


def test_mean_interval_is_students_t():
    mean, half, n = MeanInterval([1.0, 2.0, 3.0])
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.303 / math.sqrt(3), abs=1e-3)
    mean, half, n = MeanInterval([5.0] * 41)  # no spread: a zero interval
    assert (mean, half, n) == (5.0, 0.0, 41)
    assert math.isnan(MeanInterval([2.0])[1]) and MeanInterval([])[2] == 0
    # beyond the table, 1.96 + 2.4 / df against t(0.975, 60) = 2.000
    values = [float(i % 2) for i in range(61)]
    half_61 = MeanInterval(values)[1]
    std = math.sqrt(sum((v - 30 / 61) ** 2 for v in values) / 60)
    assert half_61 == pytest.approx(2.000 * std / math.sqrt(61), rel=2e-3)


def test_the_report_compares_grid_and_ranging_per_hose(tmp_path):
    campaign = CampaignConfig(
        name="hoses",
        scenario="path_following",
        grid={"path": ["paper_path_1", "paper_path_2"], "estimator": ["grid", "ranging"]},
        metrics=["tracking_error_mean_mm", "coverage"],
    )
    table = ResultsTable(tmp_path / "results.csv", campaign.AxisNames())
    table.columns += ["tracking_error_mean_mm", "coverage"]
    errors = {("paper_path_1", "grid"): [7.0, 8.0], ("paper_path_1", "ranging"): [2.0, 3.0]}
    errors |= {("paper_path_2", "grid"): [6.0, 6.0], ("paper_path_2", "ranging"): [2.5, 99.0]}
    for (path, estimator), values in errors.items():
        for k, value in enumerate(values):
            failed = value == 99.0  # a failed job is drawn, not averaged
            table.rows.append(
                {"path": path, "estimator": estimator, "success": not failed, "job_id": f"{k}",
                 "tracking_error_mean_mm": value, "coverage": 1.0}
            )  # fmt: skip
    page = WriteReport(tmp_path, campaign, table, 8, GetTask("path_following")).read_text()
    assert page.count("<svg") == 4  # 2 metrics x 2 axes, each a box plot with its points
    means = page[page.index("Means and 95 % intervals") : page.index("<h2>Results")]
    rows = dict(re.findall(r"<tr><td>(\w+)</td><td>([^<]*)</td>", means))
    # estimator grid: 7, 8, 6, 6 -> mean 6.75, t(3) x std / 2 = 3.182 x 0.957 / 2
    assert rows["grid"] == "6.75 ± 1.5 (4)"
    assert rows["ranging"] == "2.5 ± 1.2 (3)"  # the failed job left out
    # paper_path_2: 6, 6, 2.5 -> mean 4.833, std 2.021, t(2) = 4.303: 5.02
    assert rows["paper_path_2"] == "4.833 ± 5 (3)"
