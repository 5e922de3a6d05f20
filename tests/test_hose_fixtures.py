"""Scene variants around the followed hose: brackets (a count, or the old true/false),
clamps, a crossing hose; their places, shapes and refusals."""

import numpy as np
import pytest
from pydrake.common.yaml import yaml_load_typed
from pydrake.geometry import Role, SceneGraph
from pydrake.multibody.plant import MultibodyPlant

from guidedarm.systems.config_checks import CheckFields
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.scene.hose_fixtures import (
    BRACKET_INSET,
    BracketCount,
    BracketPositions,
    ClampPositions,
)
from guidedarm.systems.scene.hose_geometry import (
    HoseConfig,
    ReadCenterline,
    RegisterHose,
)

R = 0.01


def _Scene(config: HoseConfig, points: np.ndarray):
    """(inspector, hose and crossing GeometryIds) of `points` registered with `config`."""
    plant = MultibodyPlant(0.0)
    scene_graph = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    ids = RegisterHose(plant, points, config)
    return scene_graph.model_inspector(), ids


def _Named(inspector, prefix: str) -> dict:
    """{name: (X_WG, shape)} of the proximity geometries whose name starts with prefix."""
    found = {}
    for g in inspector.GetAllGeometryIds(Role.kProximity):
        if inspector.GetName(g).startswith(prefix):
            found[inspector.GetName(g)] = (inspector.GetPoseInFrame(g), inspector.GetShape(g))
    return found


def test_bracket_count_keeps_true_and_false():
    assert (BracketCount(True), BracketCount(False), BracketCount(3)) == (2, 0, 3)
    for text, count in (
        ("{}", 2),
        ("brackets: false", 0),
        ("brackets: true", 2),
        ("brackets: 3", 3),
    ):
        assert BracketCount(yaml_load_typed(schema=HoseConfig, data=text).brackets) == count
    with pytest.raises(ConfigurationError, match="brackets"):
        CheckFields(HoseConfig(brackets=-1))
    with pytest.raises(ConfigurationError, match="clamps"):
        CheckFields(HoseConfig(clamps=51))


def test_positions_along_the_hose():
    assert BracketPositions(0.6, 0) == []
    assert BracketPositions(0.6, 1) == [BRACKET_INSET]
    np.testing.assert_allclose(BracketPositions(0.6, 3), [0.05, 0.55, 0.3])
    np.testing.assert_allclose(BracketPositions(0.6, 4), [0.05, 0.55, 0.05 + 0.5 / 3, 0.05 + 1 / 3])
    np.testing.assert_allclose(ClampPositions(0.6, 2), [0.175, 0.425])


def test_three_brackets_two_clamps_and_a_crossing_hose_on_a_straight_hose():
    """A straight 0.6 m hose along x at z = 0.15 m: the middle bracket's collar and post at
    x = 0.3, the clamps at 0.175 and 0.425 m (radius 12 mm), the crossing hose under the
    middle along y with 40 mm between the surfaces, its id returned with the hose's."""
    points = np.column_stack([np.linspace(0, 0.6, 61), np.zeros(61), np.full(61, 0.15)])
    config = HoseConfig(brackets=3, clamps=2, crossing_clearance=0.04)
    inspector, ids = _Scene(config, points)
    collars = _Named(inspector, "hose_bracket_")
    assert sorted(collars) == sorted(
        f"hose_bracket_{n}_{p}" for n in ("start", "end", "middle_1") for p in ("collar", "post")
    )
    X, collar = collars["hose_bracket_middle_1_collar"]
    np.testing.assert_allclose(X.translation(), [0.3, 0, 0.15], atol=1e-12)
    assert collar.radius() == pytest.approx(R + 0.003)
    X, post = collars["hose_bracket_middle_1_post"]
    np.testing.assert_allclose(X.translation(), [0.3, 0, 0.07], atol=1e-12)
    assert post.height() == pytest.approx(0.14)
    clamps = _Named(inspector, "hose_clamp_")
    np.testing.assert_allclose(
        sorted(X.translation()[0] for X, _ in clamps.values()), [0.175, 0.425], atol=1e-12
    )
    np.testing.assert_allclose([shape.radius() for _, shape in clamps.values()], R + 0.002)
    ((X, crossing),) = _Named(inspector, "crossing_hose").values()
    np.testing.assert_allclose(X.translation(), [0.3, 0, 0.15 - 0.02 - 0.04], atol=1e-12)
    np.testing.assert_allclose(np.abs(X.rotation().matrix()[:, 2]), [0, 1, 0], atol=1e-12)
    assert crossing.radius() == pytest.approx(R)
    assert len(ids) == 60 + 1


def test_the_default_scene_is_the_two_end_brackets():
    inspector, _ = _Scene(HoseConfig(), ReadCenterline("paper_path_1"))
    assert sorted(_Named(inspector, "hose_bracket_")) == sorted(
        f"hose_bracket_{n}_{p}" for n in ("start", "end") for p in ("collar", "post")
    )
    assert not _Named(inspector, "hose_clamp_") and not _Named(inspector, "crossing")


def test_a_crossing_hose_below_the_table_is_refused():
    points = np.column_stack([np.linspace(0, 0.3, 31), np.zeros(31), np.full(31, 0.05)])
    with pytest.raises(ConfigurationError, match=r"crossing_clearance 0.03 m: .* below the table"):
        _Scene(HoseConfig(crossing_clearance=0.03), points)
