"""The robot model and its controllers, against geometry and kinematics computed independently."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yourdfpy

from dexart_lite import paths, robot_model
from dexart_lite.robot import (ACTION_DIM, HAND_JOINTS, SYNERGIES, SYNERGY_CLOSED, SYNERGY_OPEN, Robot, synergy_action,
                               synergy_targets)
from dexart_lite.sim import BulletSim
from tests.scene import control_step

TIPS = ("link_3.0_tip", "link_7.0_tip", "link_11.0_tip", "link_15.0_tip")


@pytest.fixture(scope="module")
def sim_robot():
    sim = BulletSim()
    sim.create_box("table", (0.65, 0.65, 0.025), (0, 0, -0.025))
    robot = Robot(sim, (-0.5, 0.0, 0.0))
    yield sim, robot
    sim.close()


def test_committed_hand_urdf_is_what_the_generator_writes():
    assert paths.hand_urdf().read_text() == robot_model.hand_urdf_text()


def test_every_hand_link_has_an_inertial_and_names_are_unique():
    root = ET.fromstring(paths.hand_urdf().read_text())
    links = root.findall("link")
    names = [link.get("name") for link in links] + [j.get("name") for j in root.findall("joint")]
    assert len(names) == len(set(names)) and all(names)
    assert all(link.find("inertial") is not None for link in links)
    expected = {"base_link", "palm_center", *(f"link_{i}.0" for i in range(16)), *TIPS}
    assert {link.get("name") for link in links} == expected


def test_composed_robot_has_22_revolute_joints_in_both_parsers(sim_robot):
    sim, robot = sim_robot
    assert len(robot.body.movable) == ACTION_DIM == 22
    urdf = yourdfpy.URDF.load(str(robot_model.composed_urdf()), load_meshes=False)
    assert len(urdf.actuated_joint_names) == 22
    assert all(urdf.joint_map[n].type == "revolute" for n in urdf.actuated_joint_names)
    assert len(set(urdf.link_map)) == len(urdf.link_map)
    # no URDF joint damping survives the composition (PyBullet's explicit damping is unstable)
    assert "damping" not in robot_model.composed_urdf().read_text()


def test_pybullet_and_yourdfpy_agree_on_fingertip_positions(sim_robot):
    sim, robot = sim_robot
    urdf = yourdfpy.URDF.load(str(robot_model.composed_urdf()), load_meshes=False)
    rng = np.random.default_rng(0)
    tips = [robot.body.link(n) for n in TIPS]
    for _ in range(5):
        q = rng.uniform(robot.lower, robot.upper)
        sim.reset_joints(robot.body, robot.joints, q)
        pos, _ = sim.link_frames(robot.body, tips)
        cfg = dict(zip([sim.c.getJointInfo(robot.body.uid, j)[1].decode() for j in robot.joints], q))
        urdf.update_cfg(cfg)
        for name, p in zip(TIPS, pos):
            expected = urdf.get_transform(name, "world")[:3, 3] + np.array([-0.5, 0.0, 0.0])
            np.testing.assert_allclose(p, expected, atol=1e-6)
    robot.reset()


def test_init_pose_is_free_of_self_collision(sim_robot):
    sim, robot = sim_robot
    robot.reset()
    sim.step()
    assert sim.c.getContactPoints(robot.body.uid, robot.body.uid) == ()


@pytest.mark.parametrize("velocity", [(0.2, 0.0, 0.0), (0.0, -0.15, 0.1), (-0.1, 0.1, -0.15)])
def test_twist_control_tracks_a_linear_palm_velocity(sim_robot, velocity):
    sim, robot = sim_robot
    robot.reset()
    hold = robot.hand_action(robot.init_qpos[6:])
    action = np.concatenate([velocity, np.zeros(3), hold])
    start = robot.read().flange_pos
    for _ in range(10):  # 0.4 s
        control_step(sim, robot, action)
    measured = (robot.read().flange_pos - start) / 0.4
    assert np.linalg.norm(measured - velocity) <= 0.1 * np.linalg.norm(velocity)


def test_twist_control_tracks_an_angular_velocity(sim_robot):
    sim, robot = sim_robot
    robot.reset()
    omega = np.array([0.0, 0.0, 0.5])
    action = np.concatenate([np.zeros(3), omega, robot.hand_action(robot.init_qpos[6:])])
    for _ in range(5):
        control_step(sim, robot, action)
    assert np.linalg.norm(robot.read().palm_angvel - omega) <= 0.1 * np.linalg.norm(omega)


def test_hand_targets_are_reached(sim_robot):
    sim, robot = sim_robot
    robot.reset()
    for fraction in (0.2, 0.5):
        targets = robot.lower[6:] + fraction * (robot.upper[6:] - robot.lower[6:])
        action = np.concatenate([np.zeros(6), robot.hand_action(targets)])
        for _ in range(10):
            control_step(sim, robot, action)
        assert np.abs(robot.read().qpos[6:] - targets).max() < 0.05, HAND_JOINTS


def test_hand_action_mapping_round_trips(sim_robot):
    _, robot = sim_robot
    a = np.linspace(-1, 1, 16)
    np.testing.assert_allclose(robot.hand_action(robot.hand_targets(a)), a, atol=1e-12)
    np.testing.assert_allclose(robot.hand_targets(np.zeros(16)), (robot.lower[6:] + robot.upper[6:]) / 2)


def test_synergies_move_the_hand_on_straight_lines_inside_the_joint_limits(sim_robot):
    """The synergy hand: -1 is open, +1 closed, 0 half-way on every joint of the synergy; each synergy moves
    its own joints only; the projection of targets on the lines gives the synergy action back."""
    _, robot = sim_robot
    n = len(SYNERGIES)
    np.testing.assert_allclose(synergy_targets(-np.ones(n)), SYNERGY_OPEN)
    np.testing.assert_allclose(synergy_targets(np.ones(n)), SYNERGY_CLOSED)
    np.testing.assert_allclose(synergy_targets(np.zeros(n)), (SYNERGY_OPEN + SYNERGY_CLOSED) / 2)
    np.testing.assert_allclose(synergy_targets(np.full(n, 7.0)), SYNERGY_CLOSED)  # clipped like any action
    lo, hi = robot.lower[6:], robot.upper[6:]
    assert np.all((SYNERGY_OPEN >= lo) & (SYNERGY_OPEN <= hi) & (SYNERGY_CLOSED >= lo) & (SYNERGY_CLOSED <= hi))
    only_curl = synergy_targets(np.array([-1.0, 1.0, -1.0]))  # SYNERGIES: knuckles, curl, thumb
    moved = np.flatnonzero(only_curl != SYNERGY_OPEN)
    assert moved.tolist() == [2, 3, 6, 7, 10, 11]  # PIP and DIP of index, middle, ring
    a = np.array([0.3, -0.5, 0.9])
    np.testing.assert_allclose(synergy_action(synergy_targets(a)), a, atol=1e-12)
    np.testing.assert_allclose(synergy_action(robot.hand_targets(np.ones(16))), [1.0, 1.0, 1.0])  # clipped


def test_two_simulations_in_one_process_do_not_interfere():
    runs = []
    for _ in range(2):
        sims = [BulletSim(), BulletSim()]
        robots = [Robot(s, (-0.5, 0.0, 0.0)) for s in sims]
        action = np.concatenate([[0.3, 0.0, 0.1], np.zeros(3), np.zeros(16)])
        for _ in range(5):
            control_step(sims[0], robots[0], action)  # only the first one moves
        runs.append([r.read().flange_pos for r in robots])
        for s in sims:
            s.close()
            s.close()  # closing twice is safe
    moved, still = runs[0]
    assert np.linalg.norm(moved - still) > 0.05  # the first arm moved, the second did not
    np.testing.assert_allclose(still, runs[1][1], atol=1e-9)
    np.testing.assert_array_equal(moved, runs[1][0])  # and the moving one replays exactly
