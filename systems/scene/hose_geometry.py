"""The followed hose: centerline files, a random smooth path generator, and SceneGraph geometry.

A centerline is an (N, 3) array of points (m) in a frame named by HoseConfig.frame: the
world, or (path following) the arm's base frame B, which the station turns into world
coordinates with the frame's pose X_WB. The hose is registered on the plant's world body as
a chain of capsules (radius = hose radius, one per centerline segment) with proximity,
illustration and perception roles, so that the ToF sensors, contact checks and cameras all
see it; brackets (a collar and a post down to the table at world z = 0, by default one
50 mm from each end, as the metal brackets of Wawrzyniak et al.), clamps and a crossing
hose can be added (hose_fixtures.py).
"""

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Capsule
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant

from guidedarm.systems.config_checks import (
    CheckFields,
    InRange,
    Positive,
)
from guidedarm.systems.errors import ConfigurationError
from guidedarm.systems.path_following.workspace import WorkspaceConfig
from guidedarm.systems.scene.hose_fixtures import (
    BracketCount,
    RegisterFixtures,
    SegmentPose,
)

HOSES_DIR = Path(__file__).resolve().parents[2] / "models" / "hoses"
MIN_HOSE_LENGTH = 0.10
# Every coordinate of a hose (m) lies within this of the origin: a few metres around a
# tabletop arm; farther is no hose the arms reach, and 1e308 overflows the geometry.
MAX_HOSE_COORDINATE = 5.0
_HOSE_COLOR = np.array([0.15, 0.45, 0.85, 1.0])


@dataclass
class HoseConfig:
    """The hose of a scene.

    centerline: a named path (`models/hoses/NAME.csv`, e.g. `paper_path_1`) or a CSV file of
        x, y, z rows (m, in `frame`; header optional); empty: set by the task (path
        following sets it from its `path` or `path_csv`).
    frame: the scoped frame of the centerline's coordinates, fixed to the world (e.g.
        `ur10e::base`); empty: the world (path following: the arm's base frame).
    diameter: hose diameter (m); the paper's shower hose is 20 mm.
    segment_length: length of one capsule of the geometry chain (m; at least 1 mm: a
        finer chain adds capsules, and collision time, without changing the hose's shape).
    brackets: the brackets holding the hose (a collar and a post to the table): true (the
        default) one 50 mm from each end, false none, an integer N that many: the two end
        ones and N - 2 evenly between (N = 1: the start one).
    clamps: hose clamps (a band, no post) evenly spread between the end brackets' places.
    crossing_clearance: > 0 adds a second, straight hose of the same diameter crossing
        under the middle of this one, perpendicular to it in plan, with this gap between
        the two surfaces (m); 0: none. Refused when it would reach below the table.
    hose_fixtures.py has the shapes; none of them is the followed hose.
    """

    centerline: str = ""
    frame: str = ""
    diameter: float = Positive(0.020)
    segment_length: float = InRange(0.001, math.inf, 0.010)
    brackets: bool | int = InRange(0, 50, True)
    clamps: int = InRange(0, 50, 0)
    crossing_clearance: float = InRange(0.0, 1.0, 0.0)


def ResolveCenterlinePath(name_or_file: str) -> Path:
    """The CSV of a named path or a file path; ConfigurationError if neither exists."""
    path = Path(name_or_file)
    named = HOSES_DIR / f"{name_or_file}.csv"
    if path.is_dir() and not named.is_file():
        raise ConfigurationError(f"centerline {path}: is a directory, not a CSV file")
    if path.suffix.lower() == ".csv" or path.is_file():
        if not path.is_file():
            raise ConfigurationError(f"centerline file not found: {path}")
        return path
    if not named.is_file():
        known = ", ".join(sorted(p.stem for p in HOSES_DIR.glob("*.csv")))
        raise ConfigurationError(f"unknown hose path '{name_or_file}' (known: {known})")
    return named


def ReadCenterline(name_or_file: str) -> np.ndarray:
    """Reads and validates a centerline CSV (x, y, z in m per row; UTF-8, with or without
    a byte-order mark). An optional header row must name the columns x,y,z in that order
    (any case, spaces allowed): another order would be read as x,y,z all the same."""
    path = ResolveCenterlinePath(name_or_file)
    try:
        lines = path.read_bytes().decode("utf-8-sig").splitlines()
    except UnicodeDecodeError as e:
        raise ConfigurationError(f"{path}: not a text CSV (byte {e.start} is not UTF-8)") from None
    except OSError as e:
        raise ConfigurationError(f"{path}: cannot read ({e.strerror})") from None
    content = [n for n, line in enumerate(lines, 1) if line.strip() and line.strip()[0] != "#"]
    rows = []
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        cells = [c.strip() for c in text.split(",")]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if not rows and number == content[0]:
                if [c.lower() for c in cells] != ["x", "y", "z"]:
                    raise ConfigurationError(
                        f"{path}:{number}: the header {text[:60]!r} must be x,y,z (the columns "
                        "are read in that order)"
                    ) from None
                continue
            raise ConfigurationError(f"{path}:{number}: not three numbers: {text[:60]!r}") from None
        if len(values) != 3:
            raise ConfigurationError(f"{path}:{number}: expected x,y,z, got {len(values)} values")
        rows.append(values)
    return ValidateCenterline(np.array(rows, float).reshape(-1, 3), str(path))


def ValidateCenterline(points: np.ndarray, source: str = "centerline") -> np.ndarray:
    """Checks finiteness, coordinates within MAX_HOSE_COORDINATE (m), no repeated points
    and a length of at least MIN_HOSE_LENGTH."""
    if len(points) < 2:
        raise ConfigurationError(f"{source}: needs at least 2 points, has {len(points)}")
    if not np.all(np.isfinite(points)):
        raise ConfigurationError(f"{source}: contains non-finite coordinates")
    if np.any(np.abs(points) > MAX_HOSE_COORDINATE):
        row = int(np.argmax(np.abs(points).max(axis=1))) + 1
        raise ConfigurationError(
            f"{source}: point {row} lies beyond {MAX_HOSE_COORDINATE:g} m of the origin "
            "(coordinates are in metres, near the robot)"
        )
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    if np.any(steps < 1e-6):
        raise ConfigurationError(f"{source}: repeated point at row {int(np.argmin(steps)) + 2}")
    if steps.sum() < MIN_HOSE_LENGTH:
        raise ConfigurationError(f"{source}: too short ({steps.sum():.3f} m < {MIN_HOSE_LENGTH} m)")
    return points


def CheckSelfClearance(centerline: np.ndarray, diameter: float, source: str) -> None:
    """Refuses a hose (ConfigurationError) whose tube of `diameter` (m) would pass through
    itself: two points of its centerline (m) farther apart along it than half a turn of
    the tightest bend the tube allows (pi x its radius) but closer than the diameter. (A
    folded or crossing centerline is no hose a robot can follow: the sensors would see
    both branches at once.)"""
    radius = diameter / 2
    spacing = radius / 4
    points = Resample(centerline, spacing)
    s = ArcLength(points)
    # Sampled, the closest approach of two stretches reads at most
    # sqrt(d^2 + spacing^2 / 2) - d long (0.08 mm for a 20 mm hose): what is refused is
    # certainly too close, and at most that much closeness slips through.
    limit = diameter
    for start in range(0, len(points), 512):
        block = points[start : start + 512]
        distance = np.linalg.norm(block[:, None, :] - points[None, :, :], axis=2)
        apart = np.abs(s[start : start + 512, None] - s[None, :]) > math.pi * radius
        distance[~apart] = np.inf
        i, j = np.unravel_index(np.argmin(distance), distance.shape)
        if distance[i, j] < limit:
            raise ConfigurationError(
                f"{source}: the hose passes through itself: its centerline {s[start + i]:.3f} m "
                f"and {s[j]:.3f} m along it come within {1000 * distance[i, j]:.1f} mm, less "
                f"than the hose's diameter ({1000 * diameter:.1f} mm)"
            )


def Resample(points: np.ndarray, spacing: float) -> np.ndarray:
    """Points at equal arc-length spacing (the last point kept) along the polyline."""
    s = ArcLength(points)
    count = max(math.ceil(s[-1] / spacing), 1)
    samples = np.linspace(0.0, s[-1], count + 1)
    return np.column_stack([np.interp(samples, s, points[:, i]) for i in range(3)])


def ArcLength(points: np.ndarray) -> np.ndarray:
    """Cumulative arc length at each point (m)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


def MinBendRadius(points: np.ndarray, window: float = 0.03) -> float:
    """Smallest radius of the circle through points `window` apart along the path (m)."""
    fine = Resample(points, 0.002)
    k = max(round(window / 0.002), 1)
    a, b, c = fine[: -2 * k], fine[k:-k], fine[2 * k :]
    if len(a) == 0:
        return math.inf
    ab, bc, ca = (np.linalg.norm(x, axis=1) for x in (b - a, c - b, a - c))
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    with np.errstate(divide="ignore"):
        radius = np.where(area2 > 1e-12, ab * bc * ca / np.maximum(2 * area2, 1e-300), np.inf)
    return float(np.min(radius))


def DistanceToCenterline(points: np.ndarray, centerline: np.ndarray) -> np.ndarray:
    """Distance of each query point (M, 3) to the centerline polyline (m)."""
    a, b = centerline[:-1], centerline[1:]
    ab = b - a
    queries = np.atleast_2d(points)
    t = np.einsum("mkj,kj->mk", queries[:, None, :] - a[None], ab) / np.sum(ab * ab, axis=1)
    t = np.clip(t, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.min(np.linalg.norm(queries[:, None, :] - closest, axis=2), axis=1)


@dataclass
class RandomPathConfig:
    """Region and shape of random paths (m, the arm's base frame B).

    The hose centre stays in an annulus around B's z axis (radius_range) and within
    z_range, and inside the workspace walls drawn in by `margin` along x and y (and within
    the workspace's z range); it starts at an azimuth within start_azimuth_deg of
    start_azimuth_centre_deg. The paths are smooth with curvature below 1 / min_bend_radius.

    Lengths and coordinates lie within MAX_HOSE_COORDINATE (5 m) of the base, the path's
    length within [MIN_HOSE_LENGTH, 10 m].
    length: the path's length (m).
    min_bend_radius: smallest bend radius of the path (m).
    radius_range: [lo, hi] distance of the hose centre from B's z axis (m).
    z_range: [lo, hi] height of the hose centre in B (m).
    max_slope_deg: steepest slope of the path against B's xy plane (deg).
    margin: distance kept from the workspace walls along x and y (m).
    start_azimuth_centre_deg: azimuth about B's z axis around which the path starts (deg).
    start_azimuth_deg: largest deviation of the start azimuth from that centre (deg).
    on_table: the hose lies on the table: flat, its centre at its radius above B's xy
        plane (the table top; z_range and max_slope_deg then stay at their defaults).
    """

    length: float = InRange(MIN_HOSE_LENGTH, 2 * MAX_HOSE_COORDINATE, 0.6)
    min_bend_radius: float = InRange(0.0, MAX_HOSE_COORDINATE, 0.10, low_open=True)
    radius_range: list[float] = InRange(0.0, MAX_HOSE_COORDINATE, factory=lambda: [0.29, 0.43])
    z_range: list[float] = InRange(
        -MAX_HOSE_COORDINATE, MAX_HOSE_COORDINATE, factory=lambda: [0.08, 0.20]
    )
    max_slope_deg: float = InRange(0.0, 90.0, 35.0, low_open=True)
    margin: float = InRange(0.0, MAX_HOSE_COORDINATE, 0.10)
    start_azimuth_centre_deg: float = 0.0
    start_azimuth_deg: float = InRange(0.0, 180.0, math.degrees(0.6))
    on_table: bool = False

    def Validate(self) -> None:
        """Raises ConfigurationError naming the first bad field."""
        CheckFields(self)
        for key in ("radius_range", "z_range"):
            bounds = getattr(self, key)
            if len(bounds) != 2 or not bounds[0] < bounds[1]:
                raise ConfigurationError(f"{key} must be [lower, upper] with lower < upper")
        default = RandomPathConfig()
        if self.on_table and (
            self.z_range != default.z_range or self.max_slope_deg != default.max_slope_deg
        ):
            raise ConfigurationError(
                "random_path.on_table lays the hose flat on the table: z_range and "
                "max_slope_deg have no effect with it; remove them"
            )


def RandomSmoothPath(
    seed: int,
    spec: RandomPathConfig | None = None,
    workspace: WorkspaceConfig | None = None,
    hose_radius: float = 0.0,
) -> np.ndarray:
    """A seeded random hose centerline (5 mm spacing) inside spec's region of the workspace
    (default the paper's cell); with spec.on_table flat at z = hose_radius (m, > 0).

    The tangent turns at a random, smoothly varying rate (kappa <= 0.8 / min_bend_radius)
    and is steered back when the path nears the region's border; attempts that still leave
    the region are redrawn from the same seeded generator.
    """
    spec = spec or RandomPathConfig()
    spec.Validate()
    box = _RandomPathBox(spec, workspace or WorkspaceConfig(), hose_radius)
    rng = np.random.default_rng(seed)
    for _ in range(200):
        path = _TryRandomPath(rng, spec, box)
        if path is not None and MinBendRadius(path) >= spec.min_bend_radius:
            return path
    raise ConfigurationError(f"no random path found for seed {seed} within the region")


def _RandomPathBox(
    spec: RandomPathConfig, workspace: WorkspaceConfig, hose_radius: float
) -> np.ndarray:
    """(2, 3) lower and upper corners of the box the random path stays in: the workspace
    drawn in by the margin along x and y, its z range cut to spec.z_range (on the table:
    z = hose_radius, inside the workspace's z range)."""
    lower = workspace.Lower() + [spec.margin, spec.margin, 0.0]
    upper = workspace.Upper() - [spec.margin, spec.margin, 0.0]
    z_range = [hose_radius, hose_radius] if spec.on_table else spec.z_range
    lower[2], upper[2] = max(lower[2], z_range[0]), min(upper[2], z_range[1])
    flat = upper[2] == lower[2] and spec.on_table  # on the table: z fixed
    if np.any(lower[:2] >= upper[:2]) or not (upper[2] > lower[2] or flat):
        raise ConfigurationError(
            f"random_path: no room inside the workspace ({workspace.Describe()}) with a "
            f"margin of {spec.margin} m and z_range {z_range}"
            + (" (on_table: the hose's radius)" if spec.on_table else "")
        )
    return np.array([lower, upper])


def _TryRandomPath(
    rng: np.random.Generator, spec: RandomPathConfig, box: np.ndarray
) -> np.ndarray | None:
    ds = 0.005
    kappa_max = 0.8 / spec.min_bend_radius
    r0 = rng.uniform(*spec.radius_range)
    spread = math.radians(spec.start_azimuth_deg)
    phi0 = math.radians(spec.start_azimuth_centre_deg) + rng.uniform(-spread, spread)
    p = np.array([r0 * math.cos(phi0), r0 * math.sin(phi0), rng.uniform(*box[:, 2])])
    heading = phi0 + rng.choice([-1.0, 1.0]) * math.pi / 2 + rng.uniform(-0.5, 0.5)
    slope = 0.0
    points = [p.copy()]
    k_heading, k_slope = 0.0, 0.0
    max_slope = 0.0 if spec.on_table else math.radians(spec.max_slope_deg)
    for _ in range(int(spec.length / ds)):
        # Smooth random curvature (first-order filtered noise) plus a pull back inside.
        k_heading = 0.9 * k_heading + 0.1 * rng.normal(0.0, kappa_max)
        k_slope = 0.9 * k_slope + 0.1 * rng.normal(0.0, kappa_max)
        r = math.hypot(p[0], p[1])
        radial = math.atan2(p[1], p[0])
        outward = math.cos(heading - radial)
        if r > spec.radius_range[1] - 0.04 and outward > -0.3:
            k_heading = math.copysign(kappa_max, math.sin(heading - radial))
        if r < spec.radius_range[0] + 0.04 and outward < 0.3:
            k_heading = -math.copysign(kappa_max, math.sin(heading - radial))
        if p[2] > box[1, 2] - 0.03:
            k_slope = -kappa_max
        if p[2] < box[0, 2] + 0.03:
            k_slope = kappa_max
        if spec.on_table:
            k_slope = 0.0
        k_heading = float(np.clip(k_heading, -kappa_max, kappa_max))
        k_slope = float(np.clip(k_slope, -kappa_max, kappa_max))
        # Keep the total curvature (heading turns scaled by cos(slope)) under kappa_max.
        norm = math.hypot(k_heading * math.cos(slope), k_slope)
        if norm > kappa_max:
            k_heading, k_slope = k_heading * kappa_max / norm, k_slope * kappa_max / norm
        heading += k_heading * ds
        slope = float(np.clip(slope + k_slope * ds, -max_slope, max_slope))
        direction = np.array(
            [
                math.cos(heading) * math.cos(slope),
                math.sin(heading) * math.cos(slope),
                math.sin(slope),
            ]
        )
        p = p + ds * direction
        points.append(p.copy())
        r = math.hypot(p[0], p[1])
        if not (
            spec.radius_range[0] <= r <= spec.radius_range[1]
            and np.all(box[0] <= p)
            and np.all(p <= box[1])
        ):
            return None
    return np.array(points)


def WriteCenterline(points: np.ndarray, path: Path) -> None:
    """Writes a centerline CSV with an x,y,z header (m)."""
    lines = ["x,y,z"] + [f"{x:.6f},{y:.6f},{z:.6f}" for x, y, z in points]
    path.write_text("\n".join(lines) + "\n")


def RegisterHose(plant: MultibodyPlant, centerline: np.ndarray, config: HoseConfig) -> list:
    """Registers the hose (and brackets) on the world body of an unfinalized plant.

    Returns the GeometryIds of the hose capsules (proximity role), and of the crossing
    hose's, for contact checks.
    """
    if not (config.diameter > 0 and config.segment_length > 0):
        raise ConfigurationError("hose diameter and segment_length must be positive")
    CheckSelfClearance(centerline, config.diameter, config.centerline or "hose")
    radius = config.diameter / 2
    points = Resample(centerline, config.segment_length)
    world = plant.world_body()
    friction = CoulombFriction(0.5, 0.5)
    ids = []
    for i, (a, b) in enumerate(itertools.pairwise(points)):
        X_WC = SegmentPose(a, b)
        shape = Capsule(radius, float(np.linalg.norm(b - a)))
        ids.append(plant.RegisterCollisionGeometry(world, X_WC, shape, f"hose_{i}", friction))
        plant.RegisterVisualGeometry(world, X_WC, shape, f"hose_{i}", _HOSE_COLOR)
    crossing = RegisterFixtures(
        plant,
        points,
        (ArcLength(points), ArcLength(points[::-1])),
        radius,
        BracketCount(config.brackets),
        config.clamps,
        config.crossing_clearance,
    )
    return ids + crossing
