"""Pictures of the objects: ``objects show`` (one object at a few joint angles) and ``objects montage``.

Rendered with PyBullet's TinyRenderer in DIRECT mode (no display needed). The camera looks from the
robot's side (-x), from +y and from above, like the task cameras, so the functional part is in view.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure  # the object API needs no display backend (unlike pyplot)

from dexart_lite.objects import ObjectInfo
from dexart_lite.sim import BulletClient, pybullet

VIEW_DIRECTION = np.array([-0.75, 0.85, 0.65])  # from the object toward the camera (unnormalised)
CAMERA_DISTANCE = {"faucet": 0.55, "bucket": 0.8, "laptop": 0.75, "toilet": 1.35}  # m, same per category
# Joint angles for the montage tiles (rad): far enough from the reset state to show the mechanism.
MONTAGE_ANGLE = {"faucet": 0.8, "bucket": -0.6, "laptop": 1.2, "toilet": 1.0}


def render(info: ObjectInfo, q: float, size: int = 256) -> np.ndarray:
    """``(size, size, 3)`` uint8 image of ``info`` with its joint at ``q``."""
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        uid = client.loadURDF(str(info.urdf_path), useFixedBase=True, flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
        client.resetJointState(uid, 0, q)
        lo = np.minimum(client.getAABB(uid, -1)[0], client.getAABB(uid, 0)[0])
        hi = np.maximum(client.getAABB(uid, -1)[1], client.getAABB(uid, 0)[1])
        target = 0.5 * (lo + hi)
        eye = target + CAMERA_DISTANCE[info.category] * VIEW_DIRECTION / np.linalg.norm(VIEW_DIRECTION)
        view = client.computeViewMatrix(eye.tolist(), target.tolist(), [0, 0, 1])
        projection = client.computeProjectionMatrixFOV(45.0, 1.0, 0.05, 5.0)
        _, _, rgba, _, _ = client.getCameraImage(size, size, view, projection, renderer=pybullet.ER_TINY_RENDERER,
                                                 lightDirection=[-1.0, 1.5, 2.0], shadow=0)
    finally:
        client.disconnect()
    return np.reshape(np.asarray(rgba, dtype=np.uint8), (size, size, 4))[:, :, :3]


def show(info: ObjectInfo, out: Path, size: int = 256) -> list[float]:
    """Save a row of images of one object at a few joint angles; returns the angles (rad)."""
    if info.category == "faucet":
        angles = [-1.5, 0.0, 0.8, 1.5]
    else:
        angles = sorted({info.joint_lower, info.joint_init, info.joint_target, info.joint_upper})
    fig = Figure(figsize=(3 * len(angles), 3.3))
    axes = fig.subplots(1, len(angles))
    for ax, q in zip(np.atleast_1d(axes), angles):
        ax.imshow(render(info, q, size))
        ax.set_title(f"q = {q:.2f} rad", fontsize=9)
        ax.axis("off")
    fig.suptitle(f"{info.name} ({info.split} #{info.index}, template {info.template})", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    return angles


def montage(category: str, infos: list[ObjectInfo], out: Path, size: int = 200, columns: int = 6) -> None:
    """One tile per object (seen first, then unseen), all at ``MONTAGE_ANGLE[category]``."""
    rows = -(-len(infos) // columns)
    fig = Figure(figsize=(2.2 * columns, 2.4 * rows))
    axes = np.atleast_2d(fig.subplots(rows, columns))
    for ax in axes.flat:
        ax.axis("off")
    for ax, info in zip(axes.flat, infos):
        ax.imshow(render(info, MONTAGE_ANGLE[category], size))
        color = "black" if info.split == "seen" else "tab:blue"
        ax.set_title(f"{info.split} {info.index} ({info.template})\n{info.name}", fontsize=7, color=color)
    fig.suptitle(f"{category}: {sum(i.split == 'seen' for i in infos)} seen (black), "
                 f"{sum(i.split == 'unseen' for i in infos)} unseen (blue); q = {MONTAGE_ANGLE[category]} rad",
                 fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
