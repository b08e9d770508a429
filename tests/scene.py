"""A small robot scene for the foundation tests: table, robot, one known box, a sensor."""

from __future__ import annotations

import numpy as np

from dexart_lite import pointcloud as pc
from dexart_lite.camera import CameraPose
from dexart_lite.robot import ARM_LINKS, Robot
from dexart_lite.sensor import PointCloudSensor, SensorConfig
from dexart_lite.sim import BASE_LINK, BulletSim

ROBOT_BASE = (-0.5, 0.0, 0.0)
BOX_CENTRE, BOX_HALF = np.array([0.05, 0.0, 0.06]), np.array([0.1, 0.08, 0.06])  # m, world
CAMERA = CameraPose.look_at(eye=(0.0, 1.0, 0.5), target=(0.0, 0.0, 0.5))  # DexArt's laptop camera
CROP = (0.1, 1.0, -1.0, 2.0, 0.0047767, 0.6)  # DexArt's laptop crop (robot-base frame)


def control_step(sim: BulletSim, robot: Robot, action: np.ndarray, frame_skip: int = 10) -> None:
    """One control step outside an env (the env's loop does the same)."""
    q, _ = sim.joint_states(robot.body, robot.joints)
    robot.apply_action(np.clip(action, -1, 1), q)
    for i in range(frame_skip):
        robot.track_arm((i + 1) * sim.dt)
        sim.step()


def make_scene(config: SensorConfig | None = None, camera: CameraPose = CAMERA):
    sim = BulletSim(dt=0.004)
    sim.create_box("table", (0.65, 0.65, 0.025), (0, 0, -0.025))
    box = sim.create_box("box", tuple(BOX_HALF), tuple(BOX_CENTRE), rgba=(0.9, 0.2, 0.2, 1))
    robot = Robot(sim, ROBOT_BASE)
    labels = pc.LabelTable()
    labels.set(box.uid, BASE_LINK, pc.FUNCTIONAL)
    for name, link in robot.body.links.items():
        labels.set(robot.body.uid, link, pc.ARM if name in ARM_LINKS or link == BASE_LINK else pc.HAND)
    sensor = PointCloudSensor(sim, config or SensorConfig(), camera, CROP, ROBOT_BASE, labels, robot.body)
    return sim, robot, box, sensor


def box_distance(points_world: np.ndarray) -> np.ndarray:
    """Signed distance (M,) of world points to the box surface, m."""
    q = np.abs(points_world - BOX_CENTRE) - BOX_HALF
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
