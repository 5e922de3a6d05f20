"""What a real arm's joint encoders read: offsets, resolution and a compliant transmission."""

from __future__ import annotations

import numpy as np


def EncoderPositions(
    q_link: np.ndarray,
    joint_offset: np.ndarray,
    resolution: float,
    holding_torque: np.ndarray | None = None,
    stiffness: np.ndarray | None = None,
) -> np.ndarray:
    """The joint positions an arm's encoders report (rad) for its true link angles q_link
    (rad). The encoders sit on the motor side of a transmission of `stiffness` (N m/rad
    per joint, None: rigid) that carries `holding_torque` (N m, the torque the joint
    applies to its link), so the motor leads the link by holding_torque / stiffness;
    joint_offset is the true angle minus the measured one (rad); a reading is a whole
    number of `resolution` steps (rad; 0: exact)."""
    motor = np.asarray(q_link, float)
    if stiffness is not None and holding_torque is not None:
        motor = motor + np.asarray(holding_torque, float) / np.asarray(stiffness, float)
    measured = motor - np.asarray(joint_offset, float)
    if resolution > 0:
        measured = np.round(measured / resolution) * resolution
    return measured
