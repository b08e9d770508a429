"""Nominal object placement relative to the robot base, and the arm-reach check.

DexArt places each object at ``robot_base + annotated_position`` with yaw ``annotated_yaw`` and, at
every reset, adds ``U[0, rand_pos)`` on x, y **and** z plus ``U[-rand_deg, +rand_deg]`` of yaw about
the object's own origin (DexArt's scene setup: the noise on x, y and z is one-sided, ``U[0, rand_pos)``,
and dexart_lite keeps it so). We choose the nominal placement per object:

* yaw = 0 (the functional part faces the robot at -x and is visible from +y);
* z = -robot_base_z: the object stands on the table (table top at world z = 0);
* y = -rand_pos / 2, so the one-sided y noise is centred on the robot's axis;
* x maximises the worst-case reach margin over the randomisation box (1 mm grid), which puts the
  grasp point (at the reset joint state) roughly 0.3-0.45 m in front of the robot base.

Reach margin = min(REACH - distance from the shoulder, x - MIN_FRONT) over the corners of the
position box and 13 yaws spanning the yaw range, for the grasp point at the reset joint angle. The
object is rejected when the margin is negative.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from dexart_lite.objects import ROBOT_BASE, geometry
from dexart_lite.objects.model import ObjectModel
from dexart_lite.registration import SPECS

# DexArt's reset randomisation (task_setting.RANDOM_CONFIG), from registration.SPECS: position noise
# U[0, r)^3 (m), yaw +-deg; the robot base (ROBOT_BASE, world, m) faces +x.
RAND_POS = {c: SPECS[c].rand_pos for c in SPECS}
RAND_YAW_DEG = {c: SPECS[c].rand_yaw_deg for c in SPECS}
SHOULDER_HEIGHT = 0.267  # m, xArm6 joint2 above the robot base (the arm's URDF in pybullet_data)
REACH = 0.62  # m, usable distance from the shoulder
MIN_FRONT = 0.25  # m, the grasp point must be at least this far in front of the robot base
YAW_SAMPLES = 13


@dataclass(frozen=True)
class Placement:
    position: tuple[float, float, float]  # m, object root relative to the robot base (world axes)
    yaw: float  # rad
    reach_margin: float  # m, worst case over the randomisation; >= 0 means reachable
    grasp_nominal: tuple[float, float, float]  # m, grasp point at reset, nominal pose, robot-base frame


def grasp_in_body(model: ObjectModel, q: float) -> np.ndarray:
    """The grasp point (3,) in the body (root) frame at joint angle ``q``."""
    pose = model.joint.part_to_body(q)
    return pose[:3, :3] @ model.grasp_point + pose[:3, 3]


def _grasp_points(point: np.ndarray, category: str, position: np.ndarray, yaw: float) -> np.ndarray:
    """Grasp point positions ``(K, 3)`` over the randomisation extremes, robot-base frame."""
    r, deg = RAND_POS[category], RAND_YAW_DEG[category]
    yaws = np.deg2rad(np.linspace(-deg, deg, YAW_SAMPLES)) if deg > 0 else np.zeros(1)
    corners = np.array(list(itertools.product((0.0, r), repeat=3)))  # (8, 3)
    rotated = np.stack([geometry.rot_z(yaw + dy) @ point for dy in yaws])  # (Y, 3)
    return (position + corners[:, None, :] + rotated[None, :, :]).reshape(-1, 3)


def reach_margin(point: np.ndarray, category: str, position, yaw: float = 0.0) -> float:
    """Worst-case reach margin (m) of a body-frame ``point`` placed at ``position``/``yaw``."""
    pts = _grasp_points(np.asarray(point, dtype=float), category, np.asarray(position, dtype=float), yaw)
    dist = np.linalg.norm(pts - [0.0, 0.0, SHOULDER_HEIGHT], axis=1)
    return float(min(REACH - dist.max(), pts[:, 0].min() - MIN_FRONT))


def grasp_x_stats(point, category: str, position, yaw: float = 0.0) -> tuple[float, float, float]:
    """(min, mean, max) of the grasp point's x (m, robot-base frame) under the randomisation."""
    point, position = np.asarray(point, dtype=float), np.asarray(position, dtype=float)
    xs = _grasp_points(point, category, position, yaw)[:, 0]
    deg = RAND_YAW_DEG[category]
    yaws = np.deg2rad(np.linspace(-deg, deg, 181))
    mean_rotated = np.mean([(geometry.rot_z(yaw + dy) @ point)[0] for dy in yaws])
    return float(xs.min()), float(position[0] + RAND_POS[category] / 2 + mean_rotated), float(xs.max())


def choose_placement(model: ObjectModel) -> Placement:
    """The nominal placement that maximises the worst-case reach margin (see the module docstring)."""
    cat = model.category
    point = grasp_in_body(model, model.joint.init)
    y, z = -RAND_POS[cat] / 2, -ROBOT_BASE[cat][2]
    best_x, best_margin = 0.0, -np.inf
    for x in np.arange(0.0, 1.0, 0.001):
        margin = reach_margin(point, cat, (x, y, z))
        if margin > best_margin:
            best_x, best_margin = float(x), margin
    position = (round(best_x, 3), round(y, 3), round(z, 3))
    grasp = np.asarray(position) + point
    return Placement(position=position, yaw=0.0, reach_margin=round(reach_margin(point, cat, position), 4),
                     grasp_nominal=tuple(round(float(v), 4) for v in grasp))
