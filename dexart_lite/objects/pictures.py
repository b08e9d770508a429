"""Pictures of the objects: ``objects show`` (one object at a few joint angles) and ``objects montage``.

Rendered with PyBullet's TinyRenderer in DIRECT mode (no display needed), through the env's own code: the object
is loaded by ``ArticulatedObjects`` into a ``BulletSim`` and seen by a ``DepthCamera``, as in a task. The camera
looks from the robot's side (-x), from +y and from above, like the task cameras, so the functional part is in view.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure  # the object API needs no display backend (unlike pyplot)

from dexart_lite import pointcloud as pc
from dexart_lite.articulated import PART_LINK, ArticulatedObjects
from dexart_lite.camera import CameraIntrinsics, CameraPose, DepthCamera
from dexart_lite.objects import ObjectInfo
from dexart_lite.sim import BASE_LINK, BulletSim

VIEW_DIRECTION = np.array([-0.75, 0.85, 0.65])  # from the object toward the camera (unnormalised)
CAMERA_DISTANCE = {"faucet": 0.55, "bucket": 0.8, "laptop": 0.75, "toilet": 1.35}  # m, same per category
# Joint angles for the montage tiles (rad): far enough from the reset state to show the mechanism.
MONTAGE_ANGLE = {"faucet": 0.8, "bucket": -0.6, "laptop": 1.2, "toilet": 1.0}


def render(info: ObjectInfo, q: float, size: int = 256) -> np.ndarray:
    """``(size, size, 3)`` uint8 image of ``info`` with its joint at ``q``."""
    sim = BulletSim()
    try:
        objects = ArticulatedObjects(sim, [info], pc.LabelTable(), check=False)
        body = objects.activate(info.name, (0.0, 0.0, 0.0), 0.0)
        objects.set_joint(q)
        boxes = [sim.aabb(body, link) for link in (BASE_LINK, PART_LINK)]  # the body and the moving part
        lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
        target = 0.5 * (lo + hi)
        eye = target + CAMERA_DISTANCE[info.category] * VIEW_DIRECTION / np.linalg.norm(VIEW_DIRECTION)
        camera = DepthCamera(sim, CameraIntrinsics(size, size, fovy_deg=45.0, near=0.05, far=5.0),
                             CameraPose.look_at(eye, target))
        return camera.render_rgb(size, size)
    finally:
        sim.close()


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


SPLIT_COLORS = {"seen": "black", "unseen": "tab:blue", "wide": "tab:green"}  # title colour per object folder


def montage(category: str, infos: list[ObjectInfo], out: Path, size: int = 200, columns: int = 6) -> None:
    """One tile per object (in the order given: seen, unseen, then the wide training split), all at
    ``MONTAGE_ANGLE[category]``; titles coloured by split."""
    rows = -(-len(infos) // columns)
    fig = Figure(figsize=(2.2 * columns, 2.4 * rows))
    axes = np.atleast_2d(fig.subplots(rows, columns))
    for ax in axes.flat:
        ax.axis("off")
    for ax, info in zip(axes.flat, infos):
        ax.imshow(render(info, MONTAGE_ANGLE[category], size))
        color = SPLIT_COLORS[info.split]
        ax.set_title(f"{info.split} {info.index} ({info.template})\n{info.name}", fontsize=7, color=color)
    counts = ", ".join(f"{sum(i.split == s for i in infos)} {s} ({c.removeprefix('tab:')})"
                       for s, c in SPLIT_COLORS.items() if any(i.split == s for i in infos))
    fig.suptitle(f"{category}: {counts}; q = {MONTAGE_ANGLE[category]} rad", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / (2.4 * rows)))  # 0.4 in above the tiles for the suptitle
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
