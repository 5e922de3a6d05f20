"""Figures people can trust: titled, limits only when on, no offset notation, one scale."""

from __future__ import annotations

import numpy as np

from guidedarm.diagrams.plots import FinishFigure, PlotJointSeries, plt
from guidedarm.diagrams.run_context import RunContext
from guidedarm.diagrams.run_labels import HeadlineText, RunTitle
from guidedarm.diagrams.tasks.path_following.report import PlotDetectedPath
from guidedarm.diagrams.tasks.registry import LoadScenario
from guidedarm.systems.scene.hose_geometry import ReadCenterline


def LimitLines(figure) -> int:
    return sum(
        1
        for axis in figure.axes
        for line in axis.get_lines()
        if line.get_linestyle() == "--" and line.get_color() == "k"
    )


def test_limit_lines_only_when_a_limit_is_given():
    t = np.linspace(0, 1, 50)
    qdd = np.vstack([15 * np.sin(t)] * 6)
    limit = np.full(6, 1.396)
    assert LimitLines(PlotJointSeries(t, {"commanded": qdd}, "qdd", None)) == 0
    assert LimitLines(PlotJointSeries(t, {"commanded": qdd}, "qdd", (-limit, limit))) == 12
    plt.close("all")


def test_tracking_error_panel_shows_measured_minus_commanded():
    t = np.linspace(0, 1, 50)
    commanded = np.vstack([np.sin(t)] * 6)
    figure = PlotJointSeries(t, {"commanded": commanded, "measured": commanded + 2e-4}, "q (rad)")
    error_axes = figure.axes[1::2]
    assert len(error_axes) == 6
    assert np.allclose(error_axes[0].get_lines()[0].get_ydata(), 0.2)  # mrad
    assert "mrad" in error_axes[0].get_title()
    plt.close(figure)


def test_no_offset_notation_for_a_tiny_wiggle():
    t = np.linspace(0, 1, 200)
    j5 = np.vstack([1.5708 + 60e-6 * np.sin(20 * t)] * 6)
    figure = PlotJointSeries(t, {"commanded": j5}, "q (rad)")
    FinishFigure(figure)
    figure.canvas.draw()
    assert all(a.yaxis.get_offset_text().get_text() == "" for a in figure.axes)
    plt.close(figure)


def test_detected_path_views_share_one_scale_and_3d_is_equal():
    centerline = ReadCenterline("paper_path_1")
    figure = PlotDetectedPath(centerline, {"detected": centerline[::5]}, "paper_path_1")
    FinishFigure(figure, "path_following")
    flat = [a for a in figure.axes if not hasattr(a, "get_zlim")]
    spans = [np.ptp(a.get_xlim()) for a in flat] + [np.ptp(a.get_ylim()) for a in flat]
    assert np.allclose(spans, spans[0])
    (iso,) = [a for a in figure.axes if hasattr(a, "get_zlim")]
    cube = [np.ptp(iso.get_xlim3d()), np.ptp(iso.get_ylim3d()), np.ptp(iso.get_zlim3d())]
    assert np.allclose(cube, spans[0])
    plt.close(figure)


def test_titles_name_scenario_arm_and_variant():
    _, scenario, _ = LoadScenario("ur10e_waypoints", ["limits=none"])
    title = RunTitle("ur10e_waypoints", scenario, ["limits=none", "max_time=9"])
    assert title == "ur10e_waypoints · ur10e · limits=none, max_time=9"
    assert HeadlineText("tcp_path", {"T_s": 4.98, "final_error_m": 0.000995}) == (
        "T 4.98 s;  e(T) 0.000995 m"
    )


def test_figures_are_saved_as_png_and_svg_with_title_and_headline(tmp_path):
    context = RunContext(out_dir=tmp_path, title="ur10e_waypoints · ur10e")
    context.headline = {"c_min": 0.25}
    figure, axis = plt.subplots()
    axis.plot([0, 1], [0, 1])
    context.save_figure(figure, "scaling_coefficient")
    svg = (tmp_path / "scaling_coefficient.svg").read_text()
    assert (tmp_path / "scaling_coefficient.png").stat().st_size > 1000
    assert "ur10e_waypoints" in svg and "min c 0.25" in svg


def test_csv_cells_of_values_a_run_did_not_produce_are_empty(tmp_path):
    context = RunContext(out_dir=tmp_path, title="marker_occlusion")
    path = context.write_csv(
        "table", ["policy", "pressed", "error_mm", "far"], [["abort", None, float("nan"), 1e300]]
    )
    assert path.read_text().splitlines() == ["policy,pressed,error_mm,far", "abort,,,1e+300"]
    context.write_csv("inf", ["x"], [[float("inf")], [0.1234567891234]])
    assert (tmp_path / "inf.csv").read_text().splitlines() == ["x", "", "0.123456789"]
