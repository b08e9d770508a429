"""Small geometry for the experts: rotations, rigid poses, the palm mount, finger and thumb reach,
and pure pursuit on a polyline. Units: m and rad; positions are (3,) arrays, rotations (3, 3)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from dexart_lite.robot_model import MOUNT_RPY, MOUNT_XYZ


def rot_axis(axis, angle: float) -> np.ndarray:
    """Rotation matrix of ``angle`` rad about the unit ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def rotvec(rot: np.ndarray) -> np.ndarray:
    """Axis * angle (3,) of a rotation matrix (angle in [0, pi])."""
    cos = np.clip((np.trace(rot) - 1) / 2, -1.0, 1.0)
    angle = np.arccos(cos)
    if angle < 1e-9:
        return np.zeros(3)
    if angle > np.pi - 1e-6:  # near pi: take the axis from the symmetric part
        axis = np.sqrt(np.clip((np.diag(rot) + 1) / 2, 0, None))
        axis *= np.sign(np.where(np.abs(rot[2, 1] - rot[1, 2]) > 1e-9, rot[[2, 0, 1], [1, 2, 0]] - rot[[1, 2, 0], [2, 0, 1]], 1))
        return axis * angle
    return angle / (2 * np.sin(angle)) * np.array([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])


def rpy_matrix(rpy) -> np.ndarray:
    r, p, y = rpy
    return rot_axis((0, 0, 1), y) @ rot_axis((0, 1, 0), p) @ rot_axis((1, 0, 0), r)


def hand_frame(normal, fingers) -> np.ndarray:
    """Palm orientation (3, 3) from the palm normal (+x of base_link) and the finger direction (+z);
    ``fingers`` is made orthogonal to ``normal``."""
    x = np.asarray(normal, float) / np.linalg.norm(normal)
    z = np.asarray(fingers, float) - np.dot(fingers, x) * x
    z /= np.linalg.norm(z)
    return np.stack([x, np.cross(z, x), z], axis=1)


@dataclass(frozen=True)
class Pose:
    """A rigid transform: position (3,) and rotation (3, 3)."""

    p: np.ndarray
    R: np.ndarray

    def __matmul__(self, other: "Pose") -> "Pose":
        return Pose(self.p + self.R @ other.p, self.R @ other.R)

    def apply(self, point) -> np.ndarray:
        return self.p + self.R @ np.asarray(point, float)


# The palm (base_link) in the flange (link6) frame: DexArt's mount.
MOUNT = Pose(np.asarray(MOUNT_XYZ, float), rpy_matrix(MOUNT_RPY))
MOUNT_INV = Pose(-MOUNT.R.T @ MOUNT.p, MOUNT.R.T)


def finger_tip(mcp: float, pip: float, dip: float) -> np.ndarray:
    """Planar forward kinematics of a finger: tip centre (x_h, z_h) in the palm frame, m.

    x_h is the palmar direction, z_h the finger direction (index, middle and ring alike, ignoring
    their +-5 degree roll)."""
    lengths, base = (0.054, 0.0384, 0.0267), np.array([0.0, 0.0164])
    angles = np.cumsum([mcp, pip, dip])
    return base + sum(l * np.array([np.sin(a), np.cos(a)]) for l, a in zip(lengths, angles))


TUCKED_THUMB = (0.263, -0.105, 1.644, 0.78)  # thumb folded flat against the palm (6 mm proud of it)


@functools.lru_cache(maxsize=1)
def thumb_table() -> tuple[np.ndarray, np.ndarray]:
    """Thumb joint configurations (N, 4) and their tip centres (N, 3) in the palm frame, m.

    Computed once per process by forward kinematics of the hand URDF on a grid over the joint
    limits (a solver picks the configuration whose tip lands where it needs it)."""
    from dexart_lite import paths
    from dexart_lite.sim import BulletSim

    sim = BulletSim()
    hand = sim.load_urdf("hand", paths.hand_urdf(), fixed_base=True)
    joints = [hand.joint(f"joint_{i}.0") for i in range(12, 16)]
    tip = hand.link("link_15.0_tip")
    grids = [np.linspace(lo, hi, n) for lo, hi, n in zip(hand.lower[12:], hand.upper[12:], (10, 7, 8, 8))]
    configs = np.array(np.meshgrid(*grids, indexing="ij")).reshape(4, -1).T
    tips = np.empty((len(configs), 3))
    for i, config in enumerate(configs):
        sim.reset_joints(hand, joints, config)
        tips[i] = sim.link_frames(hand, [tip])[0][0]
    sim.close()
    return configs, tips


def thumb_reaching(point) -> np.ndarray:
    """The tabled thumb configuration (4,) whose tip centre is nearest to ``point`` (palm frame)."""
    configs, tips = thumb_table()
    return configs[np.argmin(np.linalg.norm(tips - np.asarray(point), axis=1))]


def pursue(path: list[np.ndarray], point: np.ndarray, lookahead: float) -> tuple[np.ndarray, int]:
    """Pure pursuit on a polyline: the point ``lookahead`` m further along ``path`` than the path point
    nearest to ``point``, and the index of the segment it lies on. Memoryless: where a hand is decides
    where it goes next, whatever brought it there."""
    dists = []
    for a, b in zip(path[:-1], path[1:]):
        ab = b - a
        u = float(np.clip(np.dot(point - a, ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0))
        dists.append((float(np.linalg.norm(a + u * ab - point)), u))
    i = int(np.argmin([d for d, _ in dists]))
    pos, left = path[i] + dists[i][1] * (path[i + 1] - path[i]), lookahead
    while True:
        seg = path[i + 1] - pos
        n = float(np.linalg.norm(seg))
        if n >= left or i + 2 >= len(path):
            return pos + seg * min(1.0, left / max(n, 1e-12)), i
        left -= n
        i, pos = i + 1, path[i + 1]
