"""Point-cloud processing, as pure functions of arrays, plus the imagined hand points.

DexArt's pipeline (``pc_processing.py``), every control step:

1. camera points -> robot-base frame (the robot base is never rotated, so this is a translation);
2. crop to the task's box ``[xmin, xmax, ymin, ymax, zmin, zmax]`` (zmin removes the table);
3. uniformly sample 512 points (repeat points to fill when fewer survive);
4. optional multiplicative noise ``p * (1 + N(0, 1) * 0.005)`` per point.

Labels: 0 functional part, 1 rest of the object, 2 hand, 3 arm (``LABELS``). Anything else in the
scene (table, pedestal) is background and dropped.

Imagined points: 8 points on each of 12 hand links, sampled once (fixed seed) from each link's
visual geometry and moved by forward kinematics every step: 96 points with label 2.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import trimesh

from dexart_lite import paths

LABELS = ("functional_part", "object", "hand", "arm")
FUNCTIONAL, OBJECT, HAND, ARM = range(4)
BACKGROUND = -1

# DexArt's IMG_CONFIG["robot"]: tips, distal and medial phalanges; no palm, no arm.
IMAGINED_LINKS = (
    "link_15.0_tip", "link_3.0_tip", "link_7.0_tip", "link_11.0_tip",
    "link_15.0", "link_3.0", "link_7.0", "link_11.0",
    "link_14.0", "link_2.0", "link_6.0", "link_10.0",
)
POINTS_PER_IMAGINED_LINK = 8
IMAGINATION_SEED = 0


class LabelTable:
    """Maps PyBullet segmentation values (``uid + ((link + 1) << 24)``) to our labels."""

    def __init__(self):
        self._table = np.full((1, 1), BACKGROUND, dtype=np.int64)  # [uid, link + 1] -> label

    def set(self, uid: int, link: int, label: int) -> None:
        rows, cols = max(self._table.shape[0], uid + 1), max(self._table.shape[1], link + 2)
        if (rows, cols) != self._table.shape:
            grown = np.full((rows, cols), BACKGROUND, dtype=np.int64)
            grown[: self._table.shape[0], : self._table.shape[1]] = self._table
            self._table = grown
        self._table[uid, link + 1] = label

    def __call__(self, seg: np.ndarray) -> np.ndarray:
        """Labels (M,) int64 for segmentation values ``seg`` (M,); unknown bodies are background."""
        uid, link1 = seg & 0xFFFFFF, seg >> 24
        inside = (uid < self._table.shape[0]) & (link1 < self._table.shape[1])
        labels = np.full(seg.shape, BACKGROUND, dtype=np.int64)
        labels[inside] = self._table[uid[inside], link1[inside]]
        return labels


def crop_mask(points: np.ndarray, bounds) -> np.ndarray:
    """Boolean mask (M,) of ``points`` (M, 3) inside ``bounds`` = (xmin, xmax, ymin, ymax, zmin, zmax)."""
    lo, hi = np.asarray(bounds[0::2]), np.asarray(bounds[1::2])
    return np.all((points >= lo) & (points <= hi), axis=1)


def sample_indices(num: int, k: int, rng: np.random.Generator) -> np.ndarray:
    """``k`` indices into ``num`` points: a uniform subset when ``num >= k``, else all points plus
    uniformly repeated ones to fill. Empty when ``num`` is 0."""
    if num == 0:
        return np.zeros(0, dtype=np.int64)
    if num >= k:
        return rng.choice(num, size=k, replace=False)
    return np.concatenate([np.arange(num), rng.integers(0, num, size=k - num)])


def multiplicative_noise(points: np.ndarray, rng: np.random.Generator, sigma: float) -> np.ndarray:
    """DexArt's point noise: each point scaled by its own ``1 + N(0, 1) * sigma`` (robot frame)."""
    return points * (1.0 + rng.normal(size=(len(points), 1)) * sigma).astype(points.dtype)


def quat_to_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4) in PyBullet's xyzw order."""
    q = np.asarray(quat, dtype=np.float64)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    out[..., 2, 0], out[..., 2, 1], out[..., 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    return out


def _visual_mesh(link) -> trimesh.Trimesh:
    """The visual geometry of a yourdfpy link (boxes and spheres), in the link frame."""
    meshes = []
    for visual in link.visuals:
        geometry = visual.geometry
        if geometry.box is not None:
            mesh = trimesh.creation.box(extents=geometry.box.size)
        elif geometry.sphere is not None:
            mesh = trimesh.creation.icosphere(subdivisions=2, radius=geometry.sphere.radius)
        else:
            raise ValueError(f"link {link.name}: only box and sphere visuals are supported for imagination")
        if visual.origin is not None:
            mesh.apply_transform(visual.origin)
        meshes.append(mesh)
    return trimesh.util.concatenate(meshes)


@lru_cache(maxsize=1)
def imagined_local_points() -> np.ndarray:
    """(12, 8, 3) points on the imagined links, each in its own link frame (m). Fixed seed."""
    import yourdfpy  # loaded once per process; only this function needs it

    hand = yourdfpy.URDF.load(str(paths.hand_urdf()), build_scene_graph=False, load_meshes=False)
    points = []
    for name in IMAGINED_LINKS:
        mesh = _visual_mesh(hand.link_map[name])
        pts, _ = trimesh.sample.sample_surface(mesh, POINTS_PER_IMAGINED_LINK, seed=IMAGINATION_SEED)
        points.append(pts)
    return np.asarray(points, dtype=np.float64)


def pose_points(local: np.ndarray, positions: np.ndarray, quats: np.ndarray) -> np.ndarray:
    """Move per-link points ``local`` (L, P, 3) by link poses (L, 3) / (L, 4) -> (L * P, 3)."""
    rot = quat_to_matrix(quats)  # (L, 3, 3)
    return (np.einsum("lij,lpj->lpi", rot, local) + positions[:, None, :]).reshape(-1, 3)
