"""A synthetic depth camera: PyBullet's TinyRenderer depth + segmentation turned into 3-D points.

Conventions. A ``CameraPose`` holds the camera position and the rotation whose columns are the
camera's x (image right), y (image down) and z (viewing direction) axes in world coordinates
(the OpenCV convention, as DexArt's ``use_opencv_trans=True`` cameras). Depth becomes points through
per-pixel rays computed once per camera: ``p_cam = depth * ray`` with ``ray = ((u - cx) / fx,
(v - cy) / fy, 1)``.

Cost (see ``benchmarks/perf/bench_sim.py``): TinyRenderer's time grows with the scene's visual triangles,
so the arm is drawn with its low-poly collision hulls (``robot_model``), and ``shadow=0`` is always
passed explicitly (PyBullet's default keeps the last value, and shadows double the cost).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dexart_lite.sim import BulletSim


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def euler_xyz_to_matrix(angles) -> np.ndarray:
    """Rotation for Euler angles (rad) about the fixed x, then y, then z axes: R = Rz @ Ry @ Rx."""
    ax, ay, az = angles
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


@dataclass(frozen=True)
class CameraPose:
    """Camera pose in world: ``position`` (3,) m, ``rotation`` (3, 3) with columns x-right, y-down, z-forward."""

    position: tuple
    rotation: tuple  # row-major 3x3, stored as nested tuples so the dataclass stays hashable

    @property
    def matrix(self) -> np.ndarray:
        return np.array(self.rotation, dtype=float)

    @staticmethod
    def from_matrix(position, rotation) -> CameraPose:
        return CameraPose(tuple(float(x) for x in position), tuple(tuple(float(x) for x in row) for row in rotation))

    @staticmethod
    def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> CameraPose:
        """A camera at ``eye`` looking at ``target`` with ``up`` pointing up in the image."""
        forward = _unit(np.subtract(target, eye))
        right = _unit(np.cross(forward, up))
        down = np.cross(forward, right)
        return CameraPose.from_matrix(eye, np.stack([right, down, forward], axis=1))

    @staticmethod
    def look_along(eye, forward, right) -> CameraPose:
        """A camera at ``eye`` looking along ``forward``; ``right`` is made orthogonal to it.

        This is how DexArt's faucet camera is given (SAPIEN's ``look_at_dir`` / ``right_dir``).
        """
        forward = _unit(forward)
        right = _unit(np.asarray(right, float) - np.dot(right, forward) * forward)
        down = np.cross(forward, right)
        return CameraPose.from_matrix(eye, np.stack([right, down, forward], axis=1))

    def perturbed(self, rng: np.random.Generator, position_std: float, rotation_std: float) -> CameraPose:
        """DexArt's per-reset pose noise: Gaussian position offset (m) and Euler-angle offset (rad)."""
        offset = rng.normal(size=3) * position_std
        rot = euler_xyz_to_matrix(rng.normal(size=3) * rotation_std)
        return CameraPose.from_matrix(np.add(self.position, offset), self.matrix @ rot)


VIEW_RADIUS = 1.0  # m: DexArt's viewpoint sphere, centred 1 m in front of the training camera


def viewpoint(pose: CameraPose, d_azimuth: float, d_polar: float, radius: float = VIEW_RADIUS) -> CameraPose:
    """``pose`` moved on DexArt's viewpoint sphere (``ROBUSTNESS_INIT_CAMERA_CONFIG``): the sphere's
    centre is the point ``radius`` m ahead of the camera; the camera's spherical angles about that
    centre (polar from world +z, azimuth from world +x, rad) change by ``d_polar`` and ``d_azimuth``,
    the distance stays ``radius`` and the camera looks at the centre with world +z up in the image.

    Laptop (camera at (0, 1, 0.5) looking at (0, 0, 0.5)): polar pi/2, azimuth pi/2; ``d_polar`` > 0
    lowers the camera, ``d_azimuth`` > 0 swings it toward -x (the robot's side)."""
    centre = np.asarray(pose.position, float) + radius * pose.matrix[:, 2]
    polar, azimuth = np.pi / 2 - np.arcsin(-pose.matrix[2, 2]), np.arctan2(-pose.matrix[1, 2], -pose.matrix[0, 2])
    polar, azimuth = polar + d_polar, azimuth + d_azimuth
    eye = centre + radius * np.array([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    return CameraPose.look_at(eye, centre)


@dataclass(frozen=True)
class CameraIntrinsics:
    """A square pinhole camera. DexArt: 64 x 64 px, fovy 69.4 deg, near 0.1 m, far 10 m."""

    width: int = 64
    height: int = 64
    fovy_deg: float = 69.4
    near: float = 0.1  # m
    far: float = 10.0  # m

    @property
    def focal(self) -> float:
        """Focal length in pixels (fx = fy, about 46.2 px at the defaults)."""
        return (self.height / 2) / np.tan(np.deg2rad(self.fovy_deg) / 2)

    def rays(self, offset_u: float = 0.5, offset_v: float = 0.5) -> np.ndarray:
        """Per-pixel ray directions (H*W, 3) in the camera frame, z = 1, row-major pixel order.

        Pixel (row r, column c) is sampled at image coordinates (u, v) = (c + offset_u, r + offset_v),
        measured from the top-left image corner; 0.5 is the pixel centre.
        """
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        u, v, f = u + offset_u, v + offset_v, self.focal
        rays = np.stack([(u - self.width / 2) / f, (v - self.height / 2) / f, np.ones_like(u)], axis=-1)
        return rays.reshape(-1, 3).astype(np.float32)


class DepthCamera:
    """Renders depth and segmentation with TinyRenderer and back-projects them to world points."""

    # OpenCV camera axes -> OpenGL camera axes (y up, z backward).
    _CV_TO_GL = np.diag([1.0, -1.0, -1.0])
    # Where TinyRenderer samples each pixel: at (c, r + 1) from the top-left corner, not at the pixel
    # centre (c + 0.5, r + 0.5). Measured against rayTestBatch (tests/test_camera.py): with pixel
    # centres, points on surfaces seen at grazing angles land up to 3 cm off; with this, < 0.1 mm.
    SAMPLE_OFFSET = (0.0, 1.0)

    def __init__(self, sim: BulletSim, intrinsics: CameraIntrinsics, pose: CameraPose):
        self.sim = sim
        self.intrinsics = intrinsics
        self._rays = intrinsics.rays(*self.SAMPLE_OFFSET)  # (H*W, 3) float32
        aspect = intrinsics.width / intrinsics.height
        self._proj = sim.projection_matrix(intrinsics.fovy_deg, aspect, intrinsics.near, intrinsics.far)
        self.set_pose(pose)

    def set_pose(self, pose: CameraPose) -> None:
        self.pose = pose
        rot_gl = pose.matrix @ self._CV_TO_GL  # columns: GL camera axes in world
        world_to_cam = np.eye(4)
        world_to_cam[:3, :3] = rot_gl.T
        world_to_cam[:3, 3] = -rot_gl.T @ np.asarray(pose.position)
        self._view = world_to_cam.T.reshape(-1).tolist()  # PyBullet wants column-major
        self._rot = pose.matrix.astype(np.float32)
        self._pos = np.asarray(pose.position, dtype=np.float32)

    def render(self) -> tuple[np.ndarray, np.ndarray]:
        """One frame as world points of the pixels that hit something.

        Returns:
            points: (M, 3) float32, world frame, m.
            seg: (M,) int64, PyBullet's ``uid + ((link + 1) << 24)`` of each point.
        """
        return self.back_project(*self.render_depth())

    def render_depth(self) -> tuple[np.ndarray, np.ndarray]:
        """TinyRenderer's raw z-buffer (H*W,) in [0, 1] and segmentation (H*W,), row-major."""
        cam = self.intrinsics
        _, _, _, depth, seg = self.sim.camera_image(cam.width, cam.height, self._view, self._proj, segmentation=True)
        return np.asarray(depth, dtype=np.float32).reshape(-1), np.asarray(seg, dtype=np.int64).reshape(-1)

    def depth_image(self, depth: np.ndarray, seg: np.ndarray) -> np.ndarray:
        """Metric depth along the optical axis (H, W) float32, m, from ``render_depth``'s buffers; 0 where
        the ray hits nothing. The input of the 2-D baseline policy (``models.depth_cnn``)."""
        cam = self.intrinsics
        z = cam.far * cam.near / (cam.far - (cam.far - cam.near) * depth)
        return np.where(seg >= 0, z, 0.0).astype(np.float32).reshape(cam.height, cam.width)

    def back_project(self, depth: np.ndarray, seg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points (M, 3) and segmentation values (M,) of the pixels that hit something."""
        cam = self.intrinsics
        hit = seg >= 0  # background pixels carry -1
        # Non-linear z-buffer value -> metric depth along the optical axis.
        z = cam.far * cam.near / (cam.far - (cam.far - cam.near) * depth[hit])
        points = (z[:, None] * self._rays[hit]) @ self._rot.T + self._pos
        return points, seg[hit]

    def render_rgb(self, width: int, height: int) -> np.ndarray:
        """A lit colour image (H, W, 3) uint8 from this camera's pose, for viewing."""
        aspect = width / height
        proj = self.sim.projection_matrix(self.intrinsics.fovy_deg, aspect, self.intrinsics.near, self.intrinsics.far)
        rgba = self.sim.camera_image(width, height, self._view, proj, segmentation=False)[2]
        return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[..., :3]
