"""Run metrics of path following on closed and self-crossing hoses: each step is compared
with the centerline near its own arc length, never with another branch that passes close."""

from __future__ import annotations

import numpy as np
import pytest

from guidedarm.diagrams.tasks.path_following.report import CenterlineMatch, Metrics
from guidedarm.systems.path_following.path_follower_math import RECORD_FIELDS
from guidedarm.systems.scene.hose_geometry import ArcLength, Resample


def _Records(p_WO: np.ndarray, S: np.ndarray) -> np.ndarray:
    records = np.zeros((len(p_WO), len(RECORD_FIELDS)))
    for i, axis in enumerate("xyz"):
        records[:, RECORD_FIELDS.index(f"O_{axis}")] = p_WO[:, i]
        records[:, RECORD_FIELDS.index(f"S_{axis}")] = S[:, i]
    records[:, RECORD_FIELDS.index("detected")] = 1.0
    return records


def _FigureEight(closed: bool) -> np.ndarray:
    """A figure eight 0.3 m x 0.2 m at z = 0.1 m, crossing itself at its centre."""
    t = np.linspace(0.0, 2 * np.pi, 241)[:-1]
    points = np.column_stack([0.15 * np.sin(t), 0.1 * np.sin(2 * t), np.full_like(t, 0.1)])
    return np.vstack([points, points[:1]]) if closed else points[:-10]


def _Circle() -> np.ndarray:
    t = np.linspace(0.0, 2 * np.pi, 121)
    return np.column_stack([0.3 + 0.1 * np.cos(t), 0.1 * np.sin(t), np.full_like(t, 0.1)])


@pytest.mark.parametrize(
    "centerline",
    [_FigureEight(closed=True), _FigureEight(closed=False), _Circle()],
    ids=["closed figure eight", "open figure eight", "closed circle"],
)
def test_tracking_and_detection_errors_on_closed_and_crossing_hoses(centerline):
    """The tool travels the whole hose 5 mm above it in 15 mm steps and sees the hose 2 mm
    to the side: every metric must say exactly that."""
    along = Resample(centerline, 0.015)
    p_WO = along + [0.0, 0.0, 0.005]
    S = along + [0.0, 0.002, 0.0]
    metrics = Metrics(_Records(p_WO, S), centerline)
    assert metrics["tracking_error_mean_mm"] == pytest.approx(5.0, abs=0.05)
    assert metrics["tracking_error_max_mm"] == pytest.approx(5.0, abs=0.05)
    assert metrics["detected_path_error_max_mm"] == pytest.approx(2.0, abs=0.2)
    assert metrics["coverage"] == 1.0


def test_a_step_across_the_crossing_is_judged_against_its_own_branch():
    """At the crossing of a figure eight, a tool 30 mm off its branch lies 0 mm from the
    other branch; matched along the arc length it is 30 mm off, and the match progresses
    monotonically to the end of the hose."""
    centerline = _FigureEight(closed=True)
    along = Resample(centerline, 0.015)
    crossing = int(np.argmin(np.linalg.norm(along[5:-5, :2], axis=1))) + 5
    tangent = along[crossing + 1] - along[crossing - 1]
    p_WO = along.copy()
    # Off the branch sideways, in the plane: onto the other branch's direction.
    sideways = np.cross([0.0, 0.0, 1.0], tangent / np.linalg.norm(tangent))
    p_WO[crossing] += 0.03 * sideways
    match = CenterlineMatch(p_WO, centerline)
    assert np.all(np.diff(match.s) >= -1e-9)
    assert match.s[-1] == pytest.approx(ArcLength(centerline)[-1], abs=0.01)
    metrics = Metrics(_Records(p_WO, along), centerline)
    assert metrics["tracking_error_max_mm"] == pytest.approx(30.0, abs=1.0)


def test_steps_beyond_the_ends_are_left_out():
    centerline = np.column_stack([np.linspace(0.2, 0.5, 31), np.zeros(31), np.full(31, 0.1)])
    along = Resample(centerline, 0.015)
    beyond = np.array([[0.53, 0.0, 0.14], [0.56, 0.0, 0.14]])  # looking for more hose
    p_WO = np.vstack([along, beyond])
    match = CenterlineMatch(p_WO, centerline)
    assert match.beyond.tolist() == [False] * len(along) + [True, True]
    assert Metrics(_Records(p_WO, p_WO), centerline)["tracking_error_max_mm"] == 0.0


def _Zigzag(legs: int = 3, leg: float = 0.06, gap: float = 0.025) -> np.ndarray:
    """Legs along +x, -x, ... `gap` apart in y, joined by half circles (m, z = 0.1 m)."""
    pieces, radius = [], gap / 2
    turn = np.linspace(-np.pi / 2, np.pi / 2, 14)[1:-1]
    for k in range(legs):
        x = np.linspace(0.0, leg, 31) if k % 2 == 0 else np.linspace(leg, 0.0, 31)
        pieces.append(np.column_stack([x, np.full(31, k * gap), np.full(31, 0.1)]))
        if k < legs - 1:
            sign, end = (1, leg) if k % 2 == 0 else (-1, 0.0)
            y = k * gap + radius + radius * np.sin(turn)
            x = end + sign * radius * np.cos(turn)
            pieces.append(np.column_stack([x, y, np.full_like(x, 0.1)]))
    return np.vstack(pieces)


def test_a_tool_crossing_between_the_legs_of_a_folded_hose_stays_on_its_leg():
    """Along the first leg to its middle at 50 mm/s (1 mm steps, 20 ms apart), then across
    to the second leg (25 mm beside it, 99 mm further along the hose) and along that: the
    match must not jump to the second leg, nor the followed length with it."""
    centerline = _Zigzag()
    first = np.column_stack([np.linspace(0.0, 0.03, 31), np.zeros(31), np.full(31, 0.1)])
    across = np.column_stack([np.full(25, 0.03), np.linspace(0.001, 0.025, 25), np.full(25, 0.1)])
    second = np.column_stack([np.linspace(0.029, 0.0, 30), np.full(30, 0.025), np.full(30, 0.1)])
    p_WO = np.vstack([first, across, second])
    records = _Records(p_WO, p_WO)
    records[:, RECORD_FIELDS.index("t")] = 0.02 * np.arange(len(p_WO))
    match = CenterlineMatch(p_WO, centerline)
    assert match.s.max() == pytest.approx(0.03, abs=0.002)
    metrics = Metrics(records, centerline, continuous=True)
    assert metrics["average_speed_mm_s"] == pytest.approx(50.0, abs=2.0)
    # the first leg's 30 mm and the hose within 25 mm of its end, of 0.18 + 0.08 m
    assert metrics["coverage"] < 0.25
