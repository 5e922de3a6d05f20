"""Checks of the robot, tool and scene models under models/.

The forward kinematics of each arm is compared with the DH tables of
/work/shared/reference/robots.md, implemented here with numpy.
"""

import json
from pathlib import Path

import numpy as np
import pytest
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.parsing import (
    LoadModelDirectives,
    Parser,
    ProcessModelDirectives,
)
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint
from pydrake.systems.framework import DiagramBuilder

MODELS = Path(__file__).parents[1] / "models"
PACKAGE_XML = MODELS / "package.xml"
PI = np.pi


def make_parser(plant):
    parser = Parser(plant)
    parser.package_map().AddPackageXml(str(PACKAGE_XML))
    return parser


# ---------------------------------------------------------------- DH tables (robots.md)
def dh_standard(theta, d, a, alpha):
    """Standard DH: Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_chain(table, q):
    """table rows: (theta_offset, d, a, alpha)."""
    T = np.eye(4)
    for (offset, d, a, alpha), qi in zip(table, q, strict=True):
        T = T @ dh_standard(qi + offset, d, a, alpha)
    return T


# (theta offset, d, a, alpha)
DH_MZ04D = [
    (0.0, 0.340, 0.0, PI / 2),
    (0.0, 0.0, 0.260, 0.0),
    (0.0, 0.0, 0.025, PI / 2),
    (0.0, 0.280, 0.0, -PI / 2),
    (0.0, 0.0, 0.0, PI / 2),
    (0.0, 0.072, 0.0, 0.0),
]
DH_UR10E = [
    (0.0, 0.1807, 0.0, PI / 2),
    (0.0, 0.0, -0.6127, 0.0),
    (0.0, 0.0, -0.57155, 0.0),
    (0.0, 0.17415, 0.0, PI / 2),
    (0.0, 0.11985, 0.0, -PI / 2),
    (0.0, 0.11655, 0.0, 0.0),
]
DH_ROVER = [
    (0.0, 0.073, 0.0, -PI / 2),
    (0.0, -0.098, 0.400, 0.0),
    (-PI / 2, 0.0, 0.0, -PI / 2),
    (0.0, 0.5009, 0.0, PI / 2),
    (0.0, 0.0, 0.0, -PI / 2),
    (0.0, 0.1909, 0.0, 0.0),
]

# name: (file, root body to weld, base frame, end frame, DH table)
ARMS = {
    "mz04d": ("mz04d/mz04d.urdf", "base", "base", "flange", DH_MZ04D),
    "ur10e": ("ur10e/ur10e.urdf", "base_link", "base", "tool0", DH_UR10E),
    "rover_arm": ("rover_arm/rover_arm.urdf", "base", "base", "tool0", DH_ROVER),
}


def rotation_angle(R):
    """Rotation angle of R, accurate for small angles."""
    s = 0.5 * np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    c = 0.5 * (np.trace(R) - 1.0)
    return np.arctan2(s, c)


def load_arm(name):
    file, root, _, _, _ = ARMS[name]
    plant = MultibodyPlant(0.0)
    make_parser(plant).AddModels(url=f"package://guidedarm/{file}")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(root))
    plant.Finalize()
    return plant


def arm_fk(plant, name, q):
    _, _, base, end, _ = ARMS[name]
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    return plant.CalcRelativeTransform(
        context, plant.GetFrameByName(base), plant.GetFrameByName(end)
    )


def revolute_joints(plant):
    joints = [plant.get_joint(i) for i in plant.GetJointIndices()]
    return [j for j in joints if isinstance(j, RevoluteJoint)]


def home(name):
    """models/<arm>/home.yaml: comments plus one flow list of 6 radians."""
    text = (MODELS / name / "home.yaml").read_text()
    lines = [line.split("#")[0] for line in text.splitlines()]
    return np.array(json.loads("".join(lines)), float)


# ---------------------------------------------------------------- arm models
@pytest.mark.parametrize("name", sorted(ARMS))
def test_arm_model_structure(name):
    plant = load_arm(name)
    joints = revolute_joints(plant)
    assert len(joints) == 6
    assert plant.num_positions() == 6
    assert plant.num_actuators() == 6
    for j in joints:
        lo, hi = j.position_lower_limits()[0], j.position_upper_limits()[0]
        assert np.isfinite(lo) and np.isfinite(hi) and lo < 0.0 < hi, j.name()
        vlo, vhi = j.velocity_lower_limits()[0], j.velocity_upper_limits()[0]
        assert np.isfinite(vhi) and vhi > 0.0 and vlo == -vhi, j.name()
        # every moving body has a positive mass and a physically valid inertia
        body = j.child_body()
        assert body.default_mass() > 0.0, body.name()
        assert body.default_spatial_inertia().IsPhysicallyValid(), body.name()
    for i in plant.GetJointActuatorIndices():
        assert plant.get_joint_actuator(i).effort_limit() > 0.0
    assert np.all(plant.GetPositionLowerLimits() <= home(name))
    assert np.all(home(name) <= plant.GetPositionUpperLimits())


@pytest.mark.parametrize("name", sorted(ARMS))
def test_arm_fk_matches_dh(name):
    plant = load_arm(name)
    table = ARMS[name][4]
    lo, hi = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    rng = np.random.default_rng(20250307)
    context = plant.CreateDefaultContext()
    base = plant.GetFrameByName(ARMS[name][2])
    end = plant.GetFrameByName(ARMS[name][3])
    for _ in range(200):
        q = rng.uniform(lo, hi)
        plant.SetPositions(context, q)
        X = plant.CalcRelativeTransform(context, base, end).GetAsMatrix4()
        T = dh_chain(table, q)
        assert np.linalg.norm(X[:3, 3] - T[:3, 3]) < 1e-9, q
        assert rotation_angle(T[:3, :3].T @ X[:3, :3]) < 1e-9, q


def test_ur10e_reference_pose():
    plant = load_arm("ur10e")
    q0 = [-PI / 2, -PI / 2, -3 * PI / 4, -PI / 4, PI / 2, PI / 4]
    X = arm_fk(plant, "ur10e", q0)
    np.testing.assert_allclose(X.translation(), [-0.17415, -0.52400, 0.27270], atol=1e-4)
    R_expected = RollPitchYaw(PI, 0.0, 3 * PI / 4).ToRotationMatrix().matrix()
    np.testing.assert_allclose(X.rotation().matrix(), R_expected, atol=1e-6)
    # tool0 is DH frame 6, with the orientation of wrist_3_link
    context = plant.CreateDefaultContext()
    X_w3_tool0 = plant.CalcRelativeTransform(
        context, plant.GetFrameByName("wrist_3_link"), plant.GetFrameByName("tool0")
    )
    assert X_w3_tool0.IsNearlyEqualTo(RigidTransform(), 1e-12)


def test_mz04d_reference_geometry():
    plant = load_arm("mz04d")
    # q = 0: upper arm horizontal, forearm down -> flange 12 mm below the base plane
    X = arm_fk(plant, "mz04d", np.zeros(6))
    np.testing.assert_allclose(X.translation(), [0.285, 0.0, -0.012], atol=1e-9)
    np.testing.assert_allclose(X.rotation().col(2), [0.0, 0.0, -1.0], atol=1e-12)
    X = arm_fk(plant, "mz04d", [0.0, PI / 2, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(X.translation(), [0.352, 0.0, 0.625], atol=1e-9)
    # reach from the J2 axis to the wrist centre, forearm aligned with the upper arm
    q3 = np.arctan2(0.280, 0.025)
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, [0.0, 0.0, q3, 0.0, 0.0, 0.0])
    X_2w = plant.CalcRelativeTransform(
        context, plant.GetFrameByName("mz04d_link2"), plant.GetFrameByName("mz04d_link5")
    )
    assert abs(np.linalg.norm(X_2w.translation()) - 0.5411) < 1e-4
    # home: flange straight down above the table
    X = arm_fk(plant, "mz04d", home("mz04d"))
    np.testing.assert_allclose(X.translation(), [0.280, 0.0, 0.553], atol=1e-9)
    np.testing.assert_allclose(X.rotation().col(2), [0.0, 0.0, -1.0], atol=1e-12)


def test_rover_reference_pose():
    plant = load_arm("rover_arm")
    X = arm_fk(plant, "rover_arm", np.zeros(6))
    np.testing.assert_allclose(X.translation(), [1.0918, -0.098, 0.073], atol=1e-9)
    np.testing.assert_allclose(X.rotation().col(2), [1.0, 0.0, 0.0], atol=1e-12)


# ---------------------------------------------------------------- tools and scenes
@pytest.mark.parametrize(
    "file",
    [
        "mz04d/gripper.urdf",
        "tools/tof_tool.urdf",
        "rover_arm/gripper_camera.urdf",
        "scenes/rover.urdf",
        "scenes/safety_cell.sdf",
    ],
)
def test_fixture_models_parse(file):
    plant = MultibodyPlant(0.0)
    scene_graph = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    (model,) = make_parser(plant).AddModels(url=f"package://guidedarm/{file}")
    plant.Finalize()
    # fixtures are rigid: one free root body (quaternion + position), no joints
    assert plant.num_positions() == 7
    bodies = plant.GetBodyIndices(model)
    assert sum(plant.get_body(b).default_mass() for b in bodies) > 0.0
    for b in bodies:
        assert plant.get_body(b).default_spatial_inertia().IsPhysicallyValid()
    assert len(scene_graph.model_inspector().GetAllGeometryIds()) > 0


DIRECTIVES = {
    "mz04d_cell": (["cell", "mz04d", "gripper", "tof_tool"], "mz04d"),
    "ur10e": (["ur10e"], "ur10e"),
    "rover_arm": (["rover", "rover_arm", "rover_gripper"], "rover_arm"),
}


def load_scene(name):
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
    directives = LoadModelDirectives(str(MODELS / "directives" / f"{name}.dmd.yaml"))
    ProcessModelDirectives(directives, plant, make_parser(plant))
    plant.Finalize()
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    return diagram, plant, scene_graph, context


def penetrations(plant, scene_graph, context):
    sg_context = scene_graph.GetMyContextFromRoot(context)
    query = scene_graph.get_query_output_port().Eval(sg_context)
    inspector = query.inspector()
    return [
        (inspector.GetName(p.id_A), inspector.GetName(p.id_B), p.depth)
        for p in query.ComputePointPairPenetration()
    ]


@pytest.mark.parametrize("name", sorted(DIRECTIVES))
def test_directive_scene_loads_and_home_is_collision_free(name):
    instances, arm = DIRECTIVES[name]
    _, plant, scene_graph, context = load_scene(name)
    for instance in instances:
        assert plant.HasModelInstanceNamed(instance)
    assert plant.num_positions() == 6
    assert plant.num_actuators() == 6
    plant_context = plant.GetMyContextFromRoot(context)
    # directive default joint positions == models/<arm>/home.yaml
    np.testing.assert_allclose(plant.GetPositions(plant_context), home(arm), atol=1e-12)
    assert penetrations(plant, scene_graph, context) == []


def test_mz04d_zero_configuration_hits_the_table():
    """Why the MZ04D needs a home: at q = 0 the flange is below the table top."""
    _, plant, scene_graph, context = load_scene("mz04d_cell")
    plant.SetPositions(plant.GetMyContextFromRoot(context), np.zeros(6))
    hits = penetrations(plant, scene_graph, context)
    assert any("table_top" in a + b for a, b, _ in hits)


def test_tof_tool_pose_and_detection_grid():
    _, plant, _, context = load_scene("mz04d_cell")
    plant_context = plant.GetMyContextFromRoot(context)
    tool = plant.GetModelInstanceByName("tof_tool")
    gripper = plant.GetModelInstanceByName("gripper")
    T = plant.GetFrameByName("tof_tool", tool)
    G = plant.GetFrameByName("gripper", gripper)

    # X_GT: l_e = 0.1597 along gripper +z, Rz(-pi/4) Ry(0) Rx(pi)
    X_GT = plant.CalcRelativeTransform(plant_context, G, T)
    X_GT_expected = RigidTransform(
        RotationMatrix.MakeZRotation(-PI / 4) @ RotationMatrix.MakeXRotation(PI),
        [0.0, 0.0, 0.1597],
    )
    assert X_GT.IsNearlyEqualTo(X_GT_expected, 1e-12)
    # the gripper sits at l_e along tool +Z (the stem direction)
    np.testing.assert_allclose(X_GT.inverse().translation(), [0.0, 0.0, 0.1597], atol=1e-12)

    # 3 x 3 grid in the tool Y-Z plane; sensor i sees row/column i of it
    a = 0.022
    X_WT = plant.CalcRelativeTransform(plant_context, plant.world_frame(), T)
    values = (-a, 0.0, a)
    sees = {
        1: [(0.0, -a, z) for z in values],
        2: [(0.0, 0.0, z) for z in values],
        3: [(0.0, a, z) for z in values],
        4: [(0.0, y, -a) for y in values],
        5: [(0.0, y, 0.0) for y in values],
        6: [(0.0, y, a) for y in values],
    }
    hits_per_point = {}
    for i, points in sees.items():
        S = plant.GetFrameByName(f"tof_sensor_{i}", tool)
        X_WS = plant.CalcRelativeTransform(plant_context, plant.world_frame(), S)
        origin, direction = X_WS.translation(), X_WS.rotation().col(2)
        for p_T in points:
            p_W = X_WT @ np.array(p_T)
            v = p_W - origin
            t = v @ direction
            assert np.linalg.norm(v - t * direction) < 1e-9, (i, p_T)
            assert 0.020 <= t <= 0.080, (i, p_T, t)  # VL6180X good range
            hits_per_point[p_T] = hits_per_point.get(p_T, 0) + 1
    assert len(hits_per_point) == 9
    assert all(n == 2 for n in hits_per_point.values())  # each point: 2 lines of sight


def test_nothing_intrudes_into_the_detection_field():
    """A 20 mm hose must pass along tool X through |y|, |z| <= 0.035 m around O."""
    _, plant, scene_graph, context = load_scene("mz04d_cell")
    plant_context = plant.GetMyContextFromRoot(context)
    X_WT = plant.CalcRelativeTransform(
        plant_context, plant.world_frame(), plant.GetFrameByName("tof_tool")
    )
    query = scene_graph.get_query_output_port().Eval(scene_graph.GetMyContextFromRoot(context))
    # sanity: a point inside the stem is reported
    inside = query.ComputeSignedDistanceToPoint(X_WT @ np.array([0.0, 0.0, 0.1]), 0.0)
    assert len(inside) > 0
    grid = np.linspace(-0.035, 0.035, 11)
    for x in np.linspace(-0.06, 0.06, 7):
        for y in grid:
            for z in grid:
                p_W = X_WT @ np.array([x, y, z])
                assert query.ComputeSignedDistanceToPoint(p_W, threshold=0.0) == [], (x, y, z)


def test_rover_gripper_camera_frame():
    _, plant, _, context = load_scene("rover_arm")
    plant_context = plant.GetMyContextFromRoot(context)
    tool0 = plant.GetFrameByName("tool0")
    X_tc = plant.CalcRelativeTransform(plant_context, tool0, plant.GetFrameByName("camera"))
    X_tt = plant.CalcRelativeTransform(plant_context, tool0, plant.GetFrameByName("gripper_tip"))
    # camera looks along the gripper +z (Drake convention: camera +Z forward)
    np.testing.assert_allclose(X_tc.rotation().col(2), [0.0, 0.0, 1.0], atol=1e-12)
    assert np.hypot(*X_tc.translation()[:2]) == pytest.approx(0.05)
    np.testing.assert_allclose(X_tt.translation(), [0.0, 0.0, 0.10], atol=1e-12)
