"""The point-cloud sensor: depth camera + labels + crop + sampling + noise + imagined hand points.

``PointCloudSensor.observe`` returns a ``PointCloud`` of ``num_points`` observed points followed by
96 imagined ones (608 x 3 at the defaults), all in the robot-base frame, with a label per point and
a mask of which points are imagined. All randomness (camera pose perturbation, subsampling, point
noise) comes from the generator the caller passes in: the env's seeded RNG.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dexart_lite import pointcloud as pc
from dexart_lite.camera import CameraIntrinsics, CameraPose, DepthCamera, viewpoint
from dexart_lite.sim import Body, BulletSim


@dataclass
class SensorConfig:
    """Settings of the point-cloud observation (DexArt's values as defaults)."""

    num_points: int = 512  # observed points after sampling
    imagination: bool = True  # append 96 imagined hand points
    point_noise: bool = False  # multiplicative per-point noise
    point_noise_std: float = 0.005  # DexArt: noise_level 0.5 * 0.01
    camera_noise: bool = False  # per-reset camera pose perturbation
    camera_position_std: float = 0.015  # m (0.5 * 0.03)
    camera_rotation_std: float = 0.05  # rad (0.5 * 0.1)
    # (azimuth, polar) half-widths (rad) of a random viewpoint on DexArt's viewpoint sphere, drawn at
    # every reset (``camera.viewpoint``); None: the nominal pose (DexArt's training camera)
    view_range: tuple[float, float] | None = None
    depth_image: bool = False  # also return the camera's metric depth image (the 2-D baseline's input)
    intrinsics: CameraIntrinsics = field(default_factory=CameraIntrinsics)

    @property
    def total_points(self) -> int:
        return self.num_points + (len(pc.IMAGINED_LINKS) * pc.POINTS_PER_IMAGINED_LINK if self.imagination else 0)


@dataclass(frozen=True)
class PointCloud:
    """One observation cloud (robot-base frame)."""

    points: np.ndarray  # (N, 3) float32, m
    labels: np.ndarray  # (N,) int64 in 0..3 (pointcloud.LABELS); -1 only for padding of an empty view
    imagined: np.ndarray  # (N,) bool, True for imagined hand points
    num_visible: int  # observed points that survived the crop, before sampling
    depth_image: np.ndarray | None = None  # (H, W) float32 metric depth of the same frame (m, 0: no hit), if asked for


class PointCloudSensor:
    """Renders, labels, crops and samples the cloud; poses the imagined points.

    Args:
        sim: the simulation.
        config: sensor settings.
        camera_pose: nominal camera pose (world).
        crop: (xmin, xmax, ymin, ymax, zmin, zmax) in the robot-base frame, m.
        robot_base: world position of the robot base (its orientation is the identity).
        labels: segmentation value -> label table, filled by the env for every body.
        robot: the robot body, for the imagined links.
    """

    def __init__(self, sim: BulletSim, config: SensorConfig, camera_pose: CameraPose, crop, robot_base,
                 labels: pc.LabelTable, robot: Body):
        self.sim, self.config, self.labels, self.robot = sim, config, labels, robot
        self.nominal_pose = camera_pose
        self.crop = tuple(float(x) for x in crop)
        self.robot_base = np.asarray(robot_base, dtype=np.float32)
        self.camera = DepthCamera(sim, config.intrinsics, camera_pose)
        self.imagined_links = [robot.link(n) for n in pc.IMAGINED_LINKS]
        self._imagined_local = pc.imagined_local_points()  # (12, 8, 3)
        n_img = self._imagined_local.shape[0] * self._imagined_local.shape[1] if config.imagination else 0
        self._imagined_mask = np.concatenate([np.zeros(config.num_points, bool), np.ones(n_img, bool)])
        self._imagined_labels = np.full(n_img, pc.HAND, dtype=np.int64)

    def reset(self, rng: np.random.Generator) -> None:
        """Start of an episode: a random viewpoint and a perturbation of the camera pose, if asked for."""
        pose = self.nominal_pose
        if self.config.view_range is not None:
            azimuth, polar = self.config.view_range
            pose = viewpoint(pose, rng.uniform(-azimuth, azimuth), rng.uniform(-polar, polar))
        if self.config.camera_noise:
            pose = pose.perturbed(rng, self.config.camera_position_std, self.config.camera_rotation_std)
        self.camera.set_pose(pose)

    def visible_points(self, depth: np.ndarray | None = None, seg: np.ndarray | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
        """All labelled, cropped camera points: (M, 3) float32 robot-base frame, (M,) labels; from the
        buffers of ``camera.render_depth`` if given, else from a new frame."""
        points, seg = self.camera.render() if depth is None else self.camera.back_project(depth, seg)
        points = points - self.robot_base
        labels = self.labels(seg)
        keep = (labels >= 0) & pc.crop_mask(points, self.crop)
        return points[keep], labels[keep]

    def imagined_points(self) -> np.ndarray:
        """(96, 3) float32 imagined hand points in the robot-base frame."""
        pos, quat = self.sim.link_frames(self.robot, self.imagined_links)
        return (pc.pose_points(self._imagined_local, pos, quat) - self.robot_base).astype(np.float32)

    def observe(self, rng: np.random.Generator) -> PointCloud:
        cfg = self.config
        depth, seg = self.camera.render_depth()
        image = self.camera.depth_image(depth, seg) if cfg.depth_image else None  # the cloud's own frame
        points, labels = self.visible_points(depth, seg)
        idx = pc.sample_indices(len(points), cfg.num_points, rng)
        if len(idx) == 0:  # nothing in view (e.g. a far-off camera override): zeros, label -1
            obs_points = np.zeros((cfg.num_points, 3), np.float32)
            obs_labels = np.full(cfg.num_points, -1, dtype=np.int64)
        else:
            obs_points, obs_labels = points[idx], labels[idx]
            if cfg.point_noise:
                obs_points = pc.multiplicative_noise(obs_points, rng, cfg.point_noise_std)
        if cfg.imagination:
            obs_points = np.concatenate([obs_points, self.imagined_points()])
            obs_labels = np.concatenate([obs_labels, self._imagined_labels])
        return PointCloud(points=obs_points.astype(np.float32), labels=obs_labels, imagined=self._imagined_mask,
                          num_visible=len(points), depth_image=image)
