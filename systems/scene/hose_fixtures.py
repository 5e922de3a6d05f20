"""What a station holds beside the followed hose: its brackets, its clamps and a second hose
crossing under it, registered on the plant's world body with the hose's roles (so that
the ToF sensors, the contact check and the cameras see them). None of it is hose the
follower should follow: these are the scene variants its estimator has to tell from the
hose (docs/path_following.md, "Scene variants").

Geometry (m):
  - a bracket: a collar (a cylinder BRACKET_COLLAR_GROWTH thicker than the hose's radius,
    BRACKET_COLLAR_LENGTH long) and a square post under it down to the table at world
    z = 0, as the metal brackets of Wawrzyniak et al. hold their hose;
  - a clamp: a band around the hose, CLAMP_GROWTH thicker than its radius and CLAMP_WIDTH
    wide, no post (a worm-drive hose clamp, DIN 3017: 9 mm band; its housing taken as
    2 mm proud of the hose);
  - the crossing hose: a straight hose of the same diameter, CROSSING_LENGTH long, under the
    followed hose's middle point, perpendicular to it in plan, `clearance` between the two
    surfaces.
"""

import numpy as np
from pydrake.geometry import Box, Capsule, Cylinder
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant

from guidedarm.systems.errors import ConfigurationError

BRACKET_INSET = 0.05
BRACKET_COLLAR_GROWTH = 0.003
BRACKET_COLLAR_LENGTH = 0.012
BRACKET_POST_WIDTH = 0.012
CLAMP_GROWTH = 0.002
CLAMP_WIDTH = 0.009
CROSSING_LENGTH = 0.3
FIXTURE_COLOR = np.array([0.55, 0.56, 0.58, 1.0])
CROSSING_COLOR = np.array([0.85, 0.35, 0.15, 1.0])
_FRICTION = CoulombFriction(0.5, 0.5)


def BracketCount(brackets: bool | int) -> int:
    """The number of brackets HoseConfig.brackets asks for: true is the two end brackets,
    false none, an integer that many."""
    if isinstance(brackets, bool):
        return 2 if brackets else 0
    return int(brackets)


def BracketPositions(length: float, count: int) -> list[float]:
    """Arc lengths (m) of `count` brackets on a hose of `length`: the first BRACKET_INSET
    from the start, the second as far from the end, the others evenly between (in that
    order)."""
    if count == 0:
        return []
    ends = [BRACKET_INSET, length - BRACKET_INSET][:count]
    inner = np.linspace(BRACKET_INSET, length - BRACKET_INSET, count)[1:-1].tolist()
    return ends + inner


def ClampPositions(length: float, count: int) -> list[float]:
    """Arc lengths (m) of `count` clamps: evenly spread between the end brackets' places,
    each in the middle of its share."""
    inside = length - 2 * BRACKET_INSET
    return [BRACKET_INSET + inside * (k + 0.5) / count for k in range(count)]


def RegisterFixtures(
    plant: MultibodyPlant,
    points: np.ndarray,
    arc_lengths: tuple[np.ndarray, np.ndarray],
    radius: float,
    brackets: int,
    clamps: int,
    crossing_clearance: float,
) -> list:
    """Registers the brackets, clamps and (crossing_clearance > 0) the crossing hose of the
    hose through `points` (N, 3, world) on the world body; arc_lengths: the points' arc
    lengths from the start and, of the points reversed, from the end (m). Returns the
    crossing hose's proximity GeometryIds. ConfigurationError when the crossing hose would
    reach below the table."""
    s, s_back = arc_lengths
    length = float(s[-1])
    for k, at_s in enumerate(BracketPositions(length, brackets)):
        # The end bracket is measured from its own end of the hose.
        name = ("start", "end")[k] if k < 2 else f"middle_{k - 1}"
        if k == 1:
            at, axis = _PointAndAxis(points[::-1], s_back, BRACKET_INSET)
        else:
            at, axis = _PointAndAxis(points, s, at_s)
        half = axis * BRACKET_COLLAR_LENGTH / 2
        X_WC = SegmentPose(at - half, at + half)
        collar = Cylinder(radius + BRACKET_COLLAR_GROWTH, BRACKET_COLLAR_LENGTH)
        height = max(at[2] - radius, 0.001)
        X_WP = RigidTransform([at[0], at[1], height / 2])
        post = Box(BRACKET_POST_WIDTH, BRACKET_POST_WIDTH, height)
        for suffix, X, shape in (("collar", X_WC, collar), ("post", X_WP, post)):
            _Register(plant, X, shape, f"hose_bracket_{name}_{suffix}", FIXTURE_COLOR)
    for k, at_s in enumerate(ClampPositions(length, clamps)):
        at, axis = _PointAndAxis(points, s, at_s)
        X_WB = SegmentPose(at - axis * CLAMP_WIDTH / 2, at + axis * CLAMP_WIDTH / 2)
        band = Cylinder(radius + CLAMP_GROWTH, CLAMP_WIDTH)
        _Register(plant, X_WB, band, f"hose_clamp_{k}", FIXTURE_COLOR)
    if crossing_clearance <= 0:
        return []
    return _RegisterCrossing(plant, points, s, radius, crossing_clearance)


def _RegisterCrossing(plant, points, s, radius, clearance) -> list:
    """The crossing hose (module docstring); its capsules' proximity GeometryIds."""
    middle, axis = _PointAndAxis(points, s, float(s[-1]) / 2)
    centre = middle - np.array([0.0, 0.0, 2 * radius + clearance])
    if centre[2] < radius:
        raise ConfigurationError(
            f"hose.crossing_clearance {clearance:g} m: the crossing hose would lie "
            f"{1000 * (radius - centre[2]):.0f} mm below the table under the hose's middle "
            f"(z = {middle[2]:.3f} m); at most {middle[2] - 3 * radius:.3f} m there"
        )
    across = np.array([-axis[1], axis[0], 0.0])
    if np.linalg.norm(across) < 1e-6:  # a vertical hose: cross along the world x axis
        across = np.array([1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    a, b = centre - across * CROSSING_LENGTH / 2, centre + across * CROSSING_LENGTH / 2
    X = SegmentPose(a, b)
    shape = Capsule(radius, CROSSING_LENGTH)
    return [_Register(plant, X, shape, "crossing_hose_0", CROSSING_COLOR)]


def _Register(plant, X_WG, shape, label, color):
    world = plant.world_body()
    geometry = plant.RegisterCollisionGeometry(world, X_WG, shape, label, _FRICTION)
    plant.RegisterVisualGeometry(world, X_WG, shape, label, color)
    return geometry


def _PointAndAxis(points: np.ndarray, s: np.ndarray, at: float) -> tuple[np.ndarray, np.ndarray]:
    """The hose's point at arc length `at` and its unit direction over the next 10 mm."""
    point = np.array([np.interp(at, s, points[:, i]) for i in range(3)])
    ahead = np.array([np.interp(at + 0.01, s, points[:, i]) for i in range(3)])
    return point, (ahead - point) / np.linalg.norm(ahead - point)


def SegmentPose(a: np.ndarray, b: np.ndarray) -> RigidTransform:
    """Pose whose z axis runs from a to b, centred between them."""
    axis = (b - a) / np.linalg.norm(b - a)
    return RigidTransform(RotationMatrix.MakeFromOneVector(axis, 2), (a + b) / 2)
