"""The experts' low-level controller: a palm pose target -> the 22-D action's twist, and hand shapes
(the action's 16 joint targets)."""

from __future__ import annotations

import numpy as np

from dexart_lite.experts.geometry import MOUNT_INV, Pose, rotvec
from dexart_lite.pointcloud import quat_to_matrix
from dexart_lite.robot import MAX_ANGULAR_SPEED, MAX_LINEAR_SPEED


class PalmController:
    """Palm pose -> flange twist (action[0:6]) with a proportional law and speed caps."""

    def __init__(self, gain: float = 6.0, rot_gain: float = 4.0, max_speed: float = 0.35, max_rot: float = 1.0):
        self.gain, self.rot_gain, self.max_speed, self.max_rot = gain, rot_gain, max_speed, max_rot

    def __call__(self, state, target: Pose, speed: float = 1.0) -> tuple[np.ndarray, float, float]:
        """Twist action (6,) toward the palm ``target``, plus the position (m) and angle (rad) errors.
        ``speed`` scales the speed caps (slow moves near a goal)."""
        flange = Pose(state.robot.flange_pos, quat_to_matrix(state.robot.flange_quat))
        goal = target @ MOUNT_INV  # flange pose that puts the palm at the target
        dp = goal.p - flange.p
        dr = rotvec(goal.R @ flange.R.T)
        v = self.gain * dp
        w = self.rot_gain * dr
        v *= min(1.0, speed * self.max_speed / max(np.linalg.norm(v), 1e-9))
        w *= min(1.0, speed * self.max_rot / max(np.linalg.norm(w), 1e-9))
        palm_err = float(np.linalg.norm(target.p - state.robot.palm_pos))
        return np.concatenate([v / MAX_LINEAR_SPEED, w / MAX_ANGULAR_SPEED]), palm_err, float(np.linalg.norm(dr))


# Hand shapes as joint targets (rad), per finger: (abduction, MCP, PIP, DIP); thumb (rot, abd, flex, flex).
def hand_shape(finger=(0.0, 0.0, 0.0, 0.0), thumb=(0.3, 0.0, 0.0, 0.0), spread: float = 0.0) -> np.ndarray:
    """16 hand joint targets: the same flexion for index, middle and ring, the abductions spread by
    ``spread`` rad (index +, ring -), and the thumb."""
    a, *flex = finger
    return np.array([a + spread, *flex, a, *flex, a - spread, *flex, *thumb], dtype=float)


OPEN = hand_shape()
