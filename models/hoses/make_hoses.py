"""Writes the hose centerlines of models/hoses/ (run once; the CSVs are checked in).

paper_path_1..4: shapes modelled on Wawrzyniak et al. (2025), section 3.3 (m, robot base
frame): 1 moderate up and down
bends on an arc around the robot; 2 more and tighter bends (radius down to about 0.11 m);
3 a long almost flat part, then a high bend closer to the base (0.33 m); 4 short, bent outward
(away from the robot) and then up, past the standard x wall (see paper_path_4.yaml).

Path 4 runs 0.25 m beside the robot's x axis and rises at 45 deg: closer to the axis (0.12 m)
or steeper (60 deg), the gripper's axis passes so near the forearm's that the wrist must
turn by over 2 rad within a few steps (joint 5 down to 0.25 rad); the MZ04D model (gripper
length estimated) then needs a reconfiguration where the hose climbs, and the follower
stopped there. At 0.25 m and 45 deg joint 5 stays above 0.5 rad.

ur10e_far_hose: for the UR10e (ur10e::base frame), 0.62-0.68 m from its base axis, beyond
the Nachi cell's walls (diagrams/scenarios/ur10e_path_following.yaml widens them): an arc
of 40 deg in front of the arm's home pose (azimuth -110 .. -70 deg), waving gently in
radius and height.
"""

from pathlib import Path

import numpy as np

from guidedarm.systems.scene.hose_geometry import (
    ArcLength,
    MinBendRadius,
    Resample,
    WriteCenterline,
)

U = np.linspace(0.0, 1.0, 3000)


def _arc(r, phi0_deg: float, phi1_deg: float, z) -> np.ndarray:
    phi = np.radians(phi0_deg + (phi1_deg - phi0_deg) * U)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def PaperPaths() -> dict[str, np.ndarray]:
    """The four centerlines, finely sampled."""
    length_1 = 0.37 * np.radians(100)
    path_1 = _arc(0.37, -50, 50, 0.11 + 0.025 * np.sin(2 * np.pi * U * length_1 / 0.42))
    length_2 = 0.38 * np.radians(110)
    path_2 = _arc(
        0.38 + 0.02 * np.sin(2 * np.pi * U * length_2 / 0.5),
        -55,
        55,
        0.11 + 0.025 * np.sin(2 * np.pi * U * length_2 / 0.34),
    )
    flat = _arc(0.40, -60, -20, 0.07 + 0.004 * U)[::3]
    v = U[1:]
    phi = np.radians(-20 + 85 * v)
    r = 0.40 - 0.07 * (1 - np.cos(np.pi * v)) / 2
    hump = np.column_stack(
        [r * np.cos(phi), r * np.sin(phi), 0.074 + 0.11 * (1 - np.cos(2 * np.pi * v)) / 2]
    )
    path_3 = np.vstack([flat, hump])
    angle = np.radians(np.linspace(0, 45, 1000))[1:]
    straight = np.column_stack(
        [np.linspace(0.28, 0.40, 1000), np.full(1000, 0.25), np.full(1000, 0.08)]
    )
    bend = np.column_stack(
        [0.40 + 0.15 * np.sin(angle), np.full(len(angle), 0.25), 0.23 - 0.15 * np.cos(angle)]
    )
    up = np.array([np.cos(np.radians(45)), 0.0, np.sin(np.radians(45))])
    rise = bend[-1] + np.linspace(0, 0.09, 500)[1:, None] * up
    path_4 = np.vstack([straight, bend, rise])
    return {f"paper_path_{i}": p for i, p in enumerate((path_1, path_2, path_3, path_4), 1)}


def UR10eFarHose() -> np.ndarray:
    """The UR10e's hose 0.62-0.68 m from its base, finely sampled."""
    length = 0.65 * np.radians(40)
    return _arc(
        0.65 + 0.03 * np.sin(2 * np.pi * U * length / 0.45),
        -110,
        -70,
        0.11 + 0.025 * np.sin(2 * np.pi * U * length / 0.40),
    )


if __name__ == "__main__":
    for name, fine in {**PaperPaths(), "ur10e_far_hose": UR10eFarHose()}.items():
        points = Resample(fine, 0.005)
        WriteCenterline(points, Path(__file__).parent / f"{name}.csv")
        print(
            f"{name}: length {ArcLength(points)[-1]:.3f} m, "
            f"min bend radius {MinBendRadius(points):.3f} m"
        )
