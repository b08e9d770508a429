"""The task's articulated objects inside one simulation: loaded once, switched without reloading.

Every object of the env's list is loaded when the env is built. The active one is placed in front
of the robot; the others are parked far away, made invisible (alpha 0, which TinyRenderer skips, so
they cost no render time) and, for free-floating bodies, pinned by a fixed constraint so that they
do not fall forever. Switching objects is then a teleport, and memory stays flat over thousands of
resets.

Object conventions (see ``urdf/objects/README.md``): the task joint is joint 0 and the functional
part is link 0; the root link is the body.
"""

from __future__ import annotations

import numpy as np

from dexart_lite import pointcloud as pc
from dexart_lite.objects import ObjectInfo
from dexart_lite.sim import BASE_LINK, JOINT_FIXED, VELOCITY_CONTROL, Body, BulletSim

PARK_SPACING = 10.0  # m between parked objects (far beyond any contact)
PART_LINK = 0  # the functional part's link index
TASK_JOINT = 0  # the task joint's index


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """Quaternion (xyzw) of a rotation by ``yaw`` rad about world z."""
    return (0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2)))


class ArticulatedObjects:
    """All objects of one env, with one of them active.

    Args:
        sim: the simulation.
        infos: the objects (from ``dexart_lite.objects``).
        labels: the segmentation label table to fill (functional part 0, the rest 1).
    """

    def __init__(self, sim: BulletSim, infos: list[ObjectInfo], labels: pc.LabelTable):
        self.sim = sim
        self.infos = {info.name: info for info in infos}
        self.bodies: dict[str, Body] = {}
        self._colours: dict[str, list[tuple[int, tuple]]] = {}
        self._pins: dict[str, int] = {}
        for i, info in enumerate(infos):
            body = sim.load_urdf(info.name, info.urdf_path, fixed_base=info.fixed_base, inertia_from_file=True)
            if body.joint(info.joint_name) != TASK_JOINT:
                raise ValueError(f"{info.name}: the task joint {info.joint_name!r} must be joint {TASK_JOINT}")
            for link in [BASE_LINK, *body.joints.values()]:
                labels.set(body.uid, link, pc.FUNCTIONAL if link == PART_LINK else pc.OBJECT)
            self._colours[info.name] = [(v[1], v[7]) for v in sim.c.getVisualShapeData(body.uid)]
            self.bodies[info.name] = body
            self._park(info.name, i)
        self.active: ObjectInfo | None = None
        self.body: Body | None = None

    @property
    def names(self) -> list[str]:
        return list(self.infos)

    def _park(self, name: str, slot: int) -> None:
        body, info = self.bodies[name], self.infos[name]
        position = (100.0 + PARK_SPACING * slot, 0.0, 0.0)
        self.sim.reset_base(body, position, (0, 0, 0, 1))
        for link, _ in self._colours[name]:
            self.sim.c.changeVisualShape(body.uid, link, rgbaColor=(0, 0, 0, 0))
        if not info.fixed_base and name not in self._pins:
            self._pins[name] = self.sim.c.createConstraint(body.uid, BASE_LINK, -1, -1, JOINT_FIXED, (0, 0, 0),
                                                           (0, 0, 0), position)

    def activate(self, name: str, position, yaw: float) -> Body:
        """Make ``name`` the active object: root frame at ``position`` (world), rotated by ``yaw``,
        task joint at its initial state, joint friction on. The previous object is parked."""
        if self.active is not None and self.active.name != name:
            self._park(self.active.name, self.names.index(self.active.name))
        info, body = self.infos[name], self.bodies[name]
        if name in self._pins:
            self.sim.c.removeConstraint(self._pins.pop(name))
        for link, rgba in self._colours[name]:
            self.sim.c.changeVisualShape(body.uid, link, rgbaColor=rgba)
        self.sim.reset_base(body, position, yaw_quaternion(yaw))
        self.sim.reset_joints(body, [TASK_JOINT], [info.joint_init])
        # Joint friction as an implicit velocity motor (URDF damping is unstable for light parts).
        self.sim.c.setJointMotorControl2(body.uid, TASK_JOINT, VELOCITY_CONTROL, targetVelocity=0.0,
                                         force=info.joint_friction)
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
        lin, ang = self.sim.c.getBaseVelocity(self.body.uid)
        return np.asarray(pos), np.asarray(lin), np.asarray(ang)
