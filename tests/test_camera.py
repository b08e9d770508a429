"""The depth camera and the point-cloud sensor, against geometry computed by hand."""

import numpy as np
import pytest

from dexart_lite import pointcloud as pc
from dexart_lite.camera import CameraIntrinsics, CameraPose, DepthCamera
from dexart_lite.sensor import SensorConfig
from dexart_lite.sim import BulletSim
from tests.scene import BOX_CENTRE, BOX_HALF, ROBOT_BASE, box_distance, control_step, make_scene

POSES = [
    CameraPose.look_at((0.0, 1.0, 0.5), (0.0, 0.0, 0.5)),  # DexArt's laptop/bucket/toilet camera
    CameraPose.look_along((-0.3, 0.6, 0.4), (0.16, -0.7, -0.35), (-1.5, -2.0, 0.0)),  # DexArt's faucet camera
    CameraPose.look_at((0.5, 0.4, 0.6), (0.0, 0.0, 0.05)),
]


def test_intrinsics_match_dexart():
    cam = CameraIntrinsics()
    assert (cam.width, cam.height) == (64, 64)
    assert cam.focal == pytest.approx(46.21, abs=0.01)  # px, fovy 69.4 deg


def test_camera_pose_axes():
    pose = POSES[0]
    np.testing.assert_allclose(pose.matrix[:, 2], [0, -1, 0], atol=1e-12)  # looks toward -y
    np.testing.assert_allclose(pose.matrix[:, 0], [-1, 0, 0], atol=1e-12)  # image right = -x
    faucet = POSES[1].matrix
    np.testing.assert_allclose(faucet.T @ faucet, np.eye(3), atol=1e-12)
    assert faucet[2, 1] < 0  # image down points down in the world


@pytest.mark.parametrize("pose", POSES)
def test_back_projection_matches_ray_casting(pose):
    """Every rendered pixel's point lies where a ray through that pixel hits the scene."""
    sim = BulletSim()
    sim.create_box("box", (0.1, 0.08, 0.05), (0.0, 0.0, 0.05))
    sim.create_box("slab", (0.3, 0.3, 0.01), (0.0, 0.0, -0.01))
    cam = DepthCamera(sim, CameraIntrinsics(), pose)
    points, seg = cam.render()
    assert len(points) > 100
    origin = np.asarray(pose.position)
    ends = origin + 3.0 * (points - origin) / np.linalg.norm(points - origin, axis=1, keepdims=True)
    hits = sim.c.rayTestBatch(np.broadcast_to(origin, points.shape).tolist(), ends.tolist())
    hit_points = np.array([h[3] for h in hits])
    same_body = np.array([h[0] for h in hits]) == (seg & 0xFFFFFF)
    err = np.linalg.norm(hit_points - points, axis=1)[same_body]
    assert same_body.mean() > 0.95
    assert np.median(err) < 1e-4 and np.mean(err < 0.005) > 0.97  # only silhouette pixels may miss
    sim.close()


def test_depth_image_is_the_metric_depth_of_the_same_frame():
    """The 2-D baseline's image: a flat floor seen straight down from 0.8 m reads 0.8 m in every pixel
    that hits it; a box of 0.1 m on it reads 0.7 m at the centre pixel; rays that hit nothing read 0."""
    sim = BulletSim()
    sim.create_box("slab", (0.2, 0.2, 0.01), (0.0, 0.0, -0.01))  # top face at z = 0
    sim.create_box("box", (0.05, 0.05, 0.05), (0.0, 0.0, 0.05))  # top face at z = 0.1
    pose = CameraPose.look_at((0.0, 0.0, 0.8), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    cam = DepthCamera(sim, CameraIntrinsics(), pose)
    depth, seg = cam.render_depth()
    image = cam.depth_image(depth, seg)
    assert image.shape == (64, 64) and image.dtype == np.float32
    assert image[32, 32] == pytest.approx(0.7, abs=2e-3)  # the box top
    assert image[0, 0] == 0.0  # beyond the 0.4 m slab: nothing hit
    floor = (image > 0.75)
    assert floor.sum() > 100 and np.allclose(image[floor], 0.8, atol=2e-3)
    # and it is the z of the very points the cloud is made of
    points, _ = cam.back_project(depth, seg)
    np.testing.assert_allclose(np.sort(0.8 - points[:, 2]), np.sort(image[image > 0]), atol=1e-5)
    sim.close()


def test_observed_points_lie_on_the_box_with_the_right_labels():
    sim, robot, box, sensor = make_scene()
    points, labels = sensor.visible_points()
    world = points + np.asarray(ROBOT_BASE)
    on_box = labels == pc.FUNCTIONAL
    assert on_box.sum() > 50
    assert np.abs(box_distance(world[on_box])).max() < 0.005
    # every point inside the box's bounding region carries the box's label
    near_box = np.all(np.abs(world - BOX_CENTRE) <= BOX_HALF + 1e-3, axis=1)
    assert np.all(labels[near_box] == pc.FUNCTIONAL)
    assert set(np.unique(labels)) <= {pc.FUNCTIONAL, pc.HAND, pc.ARM}
    assert (labels == pc.HAND).any()  # the hand is in view of this camera
    assert (points[:, 2] >= sensor.crop[4]).all()  # the table top was cropped away
    sim.close()


def test_observation_shapes_sampling_and_determinism():
    sim, robot, box, sensor = make_scene(SensorConfig(point_noise=True, camera_noise=True))
    clouds = []
    for seed in (0, 0, 1):
        rng = np.random.default_rng(seed)
        sensor.reset(rng)
        clouds.append(sensor.observe(rng))
    cloud = clouds[0]
    assert cloud.points.shape == (608, 3) and cloud.points.dtype == np.float32
    assert cloud.labels.shape == (608,) and cloud.imagined.sum() == 96 and cloud.imagined[512:].all()
    assert np.all(cloud.labels[512:] == pc.HAND) and np.all(np.isfinite(cloud.points))
    np.testing.assert_array_equal(clouds[0].points, clouds[1].points)
    assert not np.array_equal(clouds[0].points[:512], clouds[2].points[:512])
    sim.close()


def test_sampling_fills_by_repetition_and_never_invents_points():
    rng = np.random.default_rng(0)
    idx = pc.sample_indices(100, 512, rng)
    assert len(idx) == 512 and set(idx) == set(range(100))
    idx = pc.sample_indices(2000, 512, rng)
    assert len(set(idx)) == 512
    assert len(pc.sample_indices(0, 512, rng)) == 0


def test_noise_is_multiplicative_per_point():
    rng = np.random.default_rng(0)
    points = np.tile(np.array([[0.3, 0.4, 0.0]], np.float32), (20000, 1))
    noisy = pc.multiplicative_noise(points, rng, 0.005)
    scale = np.linalg.norm(noisy, axis=1) / 0.5
    np.testing.assert_allclose(noisy / scale[:, None], points, atol=1e-6)  # direction kept
    assert np.std(scale) == pytest.approx(0.005, rel=0.05)


def test_crop_mask_bounds_are_inclusive():
    points = np.array([[0.1, 0, 0.1], [0.09, 0, 0.1], [0.5, 0, 0.7]])
    np.testing.assert_array_equal(pc.crop_mask(points, (0.1, 1, -1, 1, 0, 0.6)), [True, False, False])


def test_imagined_points_follow_their_links():
    sim, robot, box, sensor = make_scene()
    local = pc.imagined_local_points()
    assert local.shape == (12, 8, 3)
    before = sensor.imagined_points()
    action = np.concatenate([[0.0, 0.2, 0.1], [0.0, 0.0, 0.5], np.linspace(-0.5, 0.8, 16)])
    for _ in range(5):
        control_step(sim, robot, action)
    after = sensor.imagined_points()
    assert np.linalg.norm(after - before, axis=1).min() > 0.01  # every imagined point moved
    # ...and each still sits at its fixed place in its link's frame
    links = [robot.body.link(n) for n in pc.IMAGINED_LINKS]
    pos, quat = sim.link_frames(robot.body, links)
    rot = pc.quat_to_matrix(quat)
    back = np.einsum("lji,lpj->lpi", rot, after.reshape(12, 8, 3) + np.asarray(ROBOT_BASE) - pos[:, None, :])
    np.testing.assert_allclose(back, local, atol=1e-5)
    sim.close()


def test_imagined_points_lie_on_the_link_geometry():
    local = pc.imagined_local_points()
    tips = local[:4]  # the four fingertip spheres, radius 12 mm, centred at the link origin
    np.testing.assert_allclose(np.linalg.norm(tips, axis=2), 0.012, atol=1e-3)
