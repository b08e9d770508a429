"""The task's articulated object inside one simulation: one object at a time, loaded per episode.

The env's objects are checked when the env is built (each URDF is loaded once and removed); at every
reset the previous episode's object is removed and the new one loaded in front of the robot, so the
world holds the robot, the scenery and exactly one object. Loading is cheap (PyBullet caches the
parsed files: ~0.3 ms per laptop, ~1.5 ms per toilet, measured with ``time.perf_counter``).

Why not load every object once and park the inactive ones far away (what this module did before):
Bullet keeps state of a body that ``saveState``/``restoreState`` do not cover (most likely its
broadphase pairs and contact caches),
and teleporting a parked object next to the robot left pairs behind that changed the next episode
(a faucet episode after a reset on another faucet differed by 0.034 rad in its first step, and a
toilet failed gymnasium's determinism check on another CPU). Removing the body removes its pairs
and contact manifolds with it, so an episode no longer depends on which objects came before.

Object conventions (see ``urdf/objects/README.md``): the task joint is joint 0 and the functional
part is link 0; the root link is the body.
"""

from __future__ import annotations

import numpy as np

from dexart_lite import pointcloud as pc
from dexart_lite.objects import ObjectInfo
from dexart_lite.sim import BASE_LINK, Body, BulletSim

PART_LINK = 0  # the functional part's link index
TASK_JOINT = 0  # the task joint's index


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """Quaternion (xyzw) of a rotation by ``yaw`` rad about world z."""
    return (0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2)))


class ArticulatedObjects:
    """The env's objects, with at most one of them in the simulation (the active one).

    Args:
        sim: the simulation.
        infos: the objects (from ``dexart_lite.objects``).
        labels: the segmentation label table to fill (functional part 0, the rest 1).
    """

    def __init__(self, sim: BulletSim, infos: list[ObjectInfo], labels: pc.LabelTable, check: bool = True):
        self.sim, self.labels = sim, labels
        self.infos = {info.name: info for info in infos}
        self.active: ObjectInfo | None = None
        self.body: Body | None = None
        if check:  # fail at construction, not in the middle of a run (a rebuilt world skips it)
            for info in infos:
                self.sim.remove(self._load(info, (0.0, 0.0, -10.0), 0.0))

    @property
    def names(self) -> list[str]:
        return list(self.infos)

    def _load(self, info: ObjectInfo, position, yaw: float) -> Body:
        body = self.sim.load_urdf(info.name, info.urdf_path, position=tuple(position),
                                  orientation=yaw_quaternion(yaw), fixed_base=info.fixed_base,
                                  inertia_from_file=True)
        if body.joint(info.joint_name) != TASK_JOINT:
            self.sim.remove(body)
            raise ValueError(f"{info.name}: the task joint {info.joint_name!r} must be joint {TASK_JOINT}")
        return body

    def remove_active(self) -> None:
        """Take the active object out of the simulation (its labels go with it)."""
        if self.body is not None:
            for link in [BASE_LINK, *self.body.joints.values()]:
                self.labels.set(self.body.uid, link, pc.BACKGROUND)
            self.sim.remove(self.body)
        self.active, self.body = None, None

    def activate(self, name: str, position, yaw: float) -> Body:
        """Load ``name`` as the active object: root frame at ``position`` (world), rotated by ``yaw``,
        task joint at its initial state, joint friction on. The previous object is removed first."""
        self.remove_active()
        info = self.infos[name]
        body = self._load(info, position, yaw)
        self.sim.reset_base(body, position, yaw_quaternion(yaw))  # exact: loadURDF's frame is ~1e-8 m off
        self.sim.reset_joints(body, [TASK_JOINT], [info.joint_init])
        for link in [BASE_LINK, *body.joints.values()]:
            self.labels.set(body.uid, link, pc.FUNCTIONAL if link == PART_LINK else pc.OBJECT)
        # Joint friction as an implicit velocity motor (URDF damping is unstable for light parts).
        self.sim.friction_motor(body, TASK_JOINT, info.joint_friction)
        self.active, self.body = info, body
        return body

    def set_joint(self, q: float) -> None:
        """Teleport the active object's task joint to ``q`` rad (pretraining data uses this)."""
        self.sim.reset_joints(self.body, [TASK_JOINT], [q])

    def joint_state(self) -> tuple[float, float]:
        """The active task joint's position (rad) and velocity (rad/s)."""
        q, qd = self.sim.joint_states(self.body, [TASK_JOINT])
        return float(q[0]), float(qd[0])

    def handle_position(self) -> np.ndarray:
        """World position (3,) of the functional part's grasp point."""
        pos, quat = self.sim.link_frames(self.body, [PART_LINK])
        return pos[0] + pc.quat_to_matrix(quat[0]) @ np.asarray(self.active.grasp_point)

    def base_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Root frame position (3,), linear (3,) and angular (3,) velocity, world frame."""
        pos, _ = self.sim.base_frame(self.body)
        lin, ang = self.sim.base_velocity(self.body)
        return np.asarray(pos), np.asarray(lin), np.asarray(ang)
