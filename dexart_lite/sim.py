"""One PyBullet world per environment: a ``BulletClient`` in DIRECT mode, bodies addressed by name.

This is the only module that imports ``pybullet`` (the object tools take it from here). Everything else talks to a ``BulletSim`` (and to
the ``Body`` records it returns), never to the global ``pybullet`` module, so two simulations in one
process cannot interfere (bullet3 #1643, panda-gym #7).

Units: metres, seconds, radians, kilograms, newtons.
"""

from __future__ import annotations

import contextlib
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


def _import_pybullet_quietly():
    """``import pybullet`` without its "pybullet build time: ..." line.

    The C module prints that line at import (on stderr in the wheels seen so far; a buffered stdout
    would carry it to the process's exit, once per forked worker). Here fds 1 and 2 point to
    /dev/null during the import and C's buffers are flushed before they are restored.
    """
    import ctypes

    sys.stdout.flush()
    sys.stderr.flush()
    devnull = os.open(os.devnull, os.O_WRONLY)
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    try:
        for fd in saved:
            os.dup2(devnull, fd)
        import pybullet as module

        ctypes.CDLL(None).fflush(None)  # anything C buffered goes to /dev/null too
    finally:
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)
    return module


pybullet = _import_pybullet_quietly()
from pybullet_utils.bullet_client import BulletClient  # noqa: E402  (pybullet is imported by now)

# Re-exported constants, so callers never import pybullet themselves.
POSITION_CONTROL = pybullet.POSITION_CONTROL
VELOCITY_CONTROL = pybullet.VELOCITY_CONTROL
JOINT_FIXED = pybullet.JOINT_FIXED
JOINT_POINT2POINT = pybullet.JOINT_POINT2POINT
ER_TINY_RENDERER = pybullet.ER_TINY_RENDERER
ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX = pybullet.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX
ER_NO_SEGMENTATION_MASK = pybullet.ER_NO_SEGMENTATION_MASK
BASE_LINK = -1  # PyBullet's link index of a body's root


@contextlib.contextmanager
def _quiet_stdout():
    """Send the C library's prints to file descriptor 1 to /dev/null for the duration."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


@dataclass
class Body:
    """A loaded body and its name tables (built once at load; never look names up per step)."""

    uid: int
    name: str
    joints: dict[str, int] = field(default_factory=dict)  # joint name -> joint index
    links: dict[str, int] = field(default_factory=dict)  # link name -> link index (root: -1)
    movable: list[int] = field(default_factory=list)  # indices of non-fixed joints, in URDF order
    lower: np.ndarray = field(default_factory=lambda: np.zeros(0))  # limits of the movable joints (rad)
    upper: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def joint(self, name: str) -> int:
        if name not in self.joints:
            raise KeyError(f"{self.name} has no joint {name!r}; joints: {', '.join(self.joints)}")
        return self.joints[name]

    def link(self, name: str) -> int:
        if name not in self.links:
            raise KeyError(f"{self.name} has no link {name!r}; links: {', '.join(self.links)}")
        return self.links[name]


class BulletSim:
    """A PyBullet world: physics time step, bodies, stepping, contacts, rendering.

    Args:
        dt: physics time step in seconds (DexArt: 0.004 s, 250 Hz).
        solver_iterations: constraint-solver iterations per step (PyBullet's default is 50).
    """

    GRAVITY = (0.0, 0.0, -9.81)  # m/s^2

    def __init__(self, dt: float = 0.004, solver_iterations: int = 50):
        self.dt = float(dt)
        with _quiet_stdout():  # BulletClient connects with options="", which pybullet echoes as "argv[0]="
            self.client: BulletClient | None = BulletClient(connection_mode=pybullet.DIRECT)
        self.client.setTimeStep(self.dt)
        self.client.setGravity(*self.GRAVITY)
        # Deterministic pair ordering: the same seed and actions replay the same contacts.
        self.client.setPhysicsEngineParameter(numSolverIterations=solver_iterations, deterministicOverlappingPairs=1)
        self.bodies: dict[str, Body] = {}

    @property
    def c(self) -> BulletClient:
        if self.client is None:
            raise RuntimeError("this simulation has been closed")
        return self.client

    # ----------------------------------------------------------------------------- bodies
    def load_urdf(self, name: str, path: Path | str, position=(0, 0, 0), orientation=(0, 0, 0, 1),
                  fixed_base: bool = True, self_collision: bool = False, inertia_from_file: bool = False) -> Body:
        """Load a URDF and index its joints and links by name.

        ``inertia_from_file``: use the URDF's inertia tensors (the generated objects have exact ones);
        otherwise PyBullet derives them from the collision shapes (right for the xArm, whose file
        tensors PyBullet rejects as "bad inertia").
        """
        flags = pybullet.URDF_MAINTAIN_LINK_ORDER
        if inertia_from_file:
            flags |= pybullet.URDF_USE_INERTIA_FROM_FILE
        if self_collision:
            # Collide links with each other, but never with any of their ancestors.
            flags |= pybullet.URDF_USE_SELF_COLLISION | pybullet.URDF_USE_SELF_COLLISION_EXCLUDE_ALL_PARENTS
        uid = self.c.loadURDF(str(path), basePosition=position, baseOrientation=orientation,
                              useFixedBase=fixed_base, flags=flags)
        return self._register(name, uid)

    def create_box(self, name: str, half_extents, position, rgba=(0.8, 0.75, 0.65, 1.0), mass: float = 0.0) -> Body:
        """A box (static when mass is 0): the table and the robot's pedestal."""
        col = self.c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half_extents)
        vis = self.c.createVisualShape(pybullet.GEOM_BOX, halfExtents=half_extents, rgbaColor=rgba)
        uid = self.c.createMultiBody(baseMass=mass, baseCollisionShapeIndex=col, baseVisualShapeIndex=vis,
                                     basePosition=position)
        return self._register(name, uid)

    def create_ground(self, name: str = "ground") -> Body:
        """A static plane through the origin, normal +z (what a free-standing object rests on)."""
        plane = self.c.createCollisionShape(pybullet.GEOM_PLANE)
        uid = self.c.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=plane)
        return self._register(name, uid)

    def _register(self, name: str, uid: int) -> Body:
        if name in self.bodies:
            raise ValueError(f"a body named {name!r} is already loaded")
        body = Body(uid=uid, name=name)
        base_name = self.c.getBodyInfo(uid)[0].decode()
        body.links[base_name] = BASE_LINK
        lower, upper = [], []
        for j in range(self.c.getNumJoints(uid)):
            info = self.c.getJointInfo(uid, j)
            joint_name, link_name = info[1].decode(), info[12].decode()
            if joint_name in body.joints or link_name in body.links:
                raise ValueError(f"{name}: duplicate joint or link name {joint_name!r}/{link_name!r}")
            body.joints[joint_name], body.links[link_name] = j, j
            if info[2] != pybullet.JOINT_FIXED:
                body.movable.append(j)
                lower.append(info[8])
                upper.append(info[9])
            # URDF damping is explicit and unstable at our gains: friction is modelled with motors instead.
            self.c.changeDynamics(uid, j, linearDamping=0.0, angularDamping=0.0, jointDamping=0.0)
        body.lower, body.upper = np.array(lower), np.array(upper)
        self.bodies[name] = body
        return body

    def remove(self, body: Body) -> None:
        self.c.removeBody(body.uid)
        del self.bodies[body.name]

    # ----------------------------------------------------------------------------- state
    def step(self, n: int = 1) -> None:
        for _ in range(n):
            self.c.stepSimulation()

    def joint_states(self, body: Body, joints: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Positions (rad) and velocities (rad/s) of ``joints``."""
        states = self.c.getJointStates(body.uid, joints)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def reset_joints(self, body: Body, joints: list[int], positions, velocities=None) -> None:
        velocities = np.zeros(len(joints)) if velocities is None else velocities
        for j, q, v in zip(joints, positions, velocities):
            self.c.resetJointState(body.uid, j, float(q), float(v))

    def link_frames(self, body: Body, links: list[int], velocity: bool = False):
        """World poses of link frames (URDF frames, not centres of mass).

        Returns positions (L, 3), quaternions (L, 4, xyzw) and, with ``velocity``, linear and
        angular velocities (L, 3) each. The root (-1) is handled too.
        """
        pos, quat, lin, ang = [], [], [], []
        states = self.c.getLinkStates(body.uid, [k for k in links if k != BASE_LINK],
                                      computeLinkVelocity=int(velocity), computeForwardKinematics=1)
        it = iter(states)
        for k in links:
            if k == BASE_LINK:
                p, q = self.base_frame(body)
                v, w = self.c.getBaseVelocity(body.uid)
            else:
                s = next(it)
                p, q = s[4], s[5]
                v, w = (s[6], s[7]) if velocity else ((0, 0, 0), (0, 0, 0))
            pos.append(p), quat.append(q), lin.append(v), ang.append(w)
        if velocity:
            return np.array(pos), np.array(quat), np.array(lin), np.array(ang)
        return np.array(pos), np.array(quat)

    def base_frame(self, body: Body):
        """World pose of the root link's URDF frame.

        ``getBasePositionAndOrientation`` returns the root's centre of mass, not its frame, so the
        inertial offset is removed here.
        """
        com_pos, com_quat = self.c.getBasePositionAndOrientation(body.uid)
        local_pos, local_quat = self.c.getDynamicsInfo(body.uid, BASE_LINK)[3:5]
        inv_pos, inv_quat = self.c.invertTransform(local_pos, local_quat)
        return self.c.multiplyTransforms(com_pos, com_quat, inv_pos, inv_quat)

    def reset_base(self, body: Body, position, orientation) -> None:
        """Place the root link's URDF frame at ``position``/``orientation`` and stop it."""
        local_pos, local_quat = self.c.getDynamicsInfo(body.uid, BASE_LINK)[3:5]
        com_pos, com_quat = self.c.multiplyTransforms(position, orientation, local_pos, local_quat)
        self.c.resetBasePositionAndOrientation(body.uid, com_pos, com_quat)
        self.c.resetBaseVelocity(body.uid, (0, 0, 0), (0, 0, 0))

    def contact_forces(self, body_a: Body, body_b: Body) -> dict[tuple[int, int], float]:
        """Summed normal force (N) per touching (link of ``body_a``, link of ``body_b``) pair."""
        forces: dict[tuple[int, int], float] = {}
        for c in self.c.getContactPoints(bodyA=body_a.uid, bodyB=body_b.uid):
            forces[c[3], c[4]] = forces.get((c[3], c[4]), 0.0) + c[9]
        return forces

    def base_velocity(self, body: Body) -> tuple[tuple, tuple]:
        """Linear (m/s) and angular (rad/s) velocity of the root, world frame."""
        return self.c.getBaseVelocity(body.uid)

    def closest_distance(self, body: Body, link_a: int, link_b: int, within: float) -> float | None:
        """Closest geometric distance (m) between two links of ``body`` (< 0: they overlap), or None when they
        are farther apart than ``within``. PyBullet reports distances minus both shapes' collision margins
        (~1 mm each); they are added back here."""
        margins = self.c.getDynamicsInfo(body.uid, link_a)[11] + self.c.getDynamicsInfo(body.uid, link_b)[11]
        points = self.c.getClosestPoints(body.uid, body.uid, within, linkIndexA=link_a, linkIndexB=link_b)
        return min((p[8] + margins for p in points), default=None)

    def detect_collisions(self) -> None:
        """A collision pass without stepping (refreshes the contact manifolds)."""
        self.c.performCollisionDetection()

    # ----------------------------------------------------------------------------- motors
    def position_motors(self, body: Body, joints: list[int], targets: list, velocities: list, forces: list) -> None:
        """Position-controlled motors on ``joints``: targets (rad), target velocities (rad/s), max forces (N*m)."""
        self.c.setJointMotorControlArray(body.uid, joints, POSITION_CONTROL, targetPositions=targets,
                                         targetVelocities=velocities, forces=forces)

    def friction_motor(self, body: Body, joint: int, force: float) -> None:
        """A velocity motor holding ``joint`` at rest with at most ``force`` (N*m): joint friction."""
        self.c.setJointMotorControl2(body.uid, joint, VELOCITY_CONTROL, targetVelocity=0.0, force=force)

    def pin_point(self, body: Body, link: int, point_in_link, world_point) -> int:
        """A point-to-point constraint holding ``point_in_link`` (m, in ``link``'s URDF frame) at ``world_point``
        (m); returns its id for :meth:`move_pin`. PyBullet takes the pivot in the link's centre-of-mass frame."""
        com_pos, com_quat = self.c.getDynamicsInfo(body.uid, link)[3:5]
        inv_pos, inv_quat = self.c.invertTransform(com_pos, com_quat)
        pivot = self.c.multiplyTransforms(inv_pos, inv_quat, list(point_in_link), (0, 0, 0, 1))[0]
        return self.c.createConstraint(body.uid, link, -1, -1, JOINT_POINT2POINT, (0, 0, 0), pivot,
                                       list(world_point))

    def move_pin(self, constraint: int, world_point, max_force: float) -> None:
        """Move a :meth:`pin_point` constraint's world point (m); it pulls with at most ``max_force`` (N)."""
        self.c.changeConstraint(constraint, list(world_point), maxForce=max_force)

    def disable_collision(self, body: Body, link_a: int, link_b: int) -> None:
        """No contacts between two links of ``body``."""
        self.c.setCollisionFilterPair(body.uid, body.uid, link_a, link_b, 0)

    # ----------------------------------------------------------------------------- model queries
    def joint_info(self, body: Body, joint: int) -> tuple:
        """PyBullet's ``getJointInfo`` tuple (limits at 8 and 9, the axis at 13)."""
        return self.c.getJointInfo(body.uid, joint)

    def link_origin_in_com(self, body: Body, link: int) -> tuple:
        """Position (3,) of ``link``'s URDF frame origin in its centre-of-mass frame (what Jacobians take)."""
        com_pos, com_quat = self.c.getDynamicsInfo(body.uid, link)[3:5]
        return self.c.invertTransform(com_pos, com_quat)[0]

    def jacobian(self, body: Body, link: int, local_position, q: list) -> tuple[tuple, tuple]:
        """Linear and angular Jacobians (3, dofs) at ``local_position`` (in ``link``'s centre-of-mass frame)
        for joint positions ``q`` (rad), zero velocities and accelerations."""
        zeros = [0.0] * len(q)
        return self.c.calculateJacobian(body.uid, link, local_position, q, zeros, zeros)

    def aabb(self, body: Body, link: int) -> tuple[tuple, tuple]:
        """World axis-aligned bounding box (low, high), m, of a link's collision shapes."""
        return self.c.getAABB(body.uid, link)

    def visual_colours(self, body: Body) -> dict[int, tuple]:
        """RGBA of each link's visual shape."""
        return {v[1]: tuple(v[7]) for v in self.c.getVisualShapeData(body.uid)}

    def set_colour(self, body: Body, link: int, rgba) -> None:
        self.c.changeVisualShape(body.uid, link, rgbaColor=rgba)

    # ----------------------------------------------------------------------------- rendering
    def projection_matrix(self, fovy_deg: float, aspect: float, near: float, far: float) -> list:
        """OpenGL projection (16 floats, column-major) of a pinhole camera."""
        return self.c.computeProjectionMatrixFOV(fovy_deg, aspect, near, far)

    def camera_image(self, width: int, height: int, view: list, projection: list, segmentation: bool) -> tuple:
        """TinyRenderer's (width, height, rgba, depth buffer, segmentation), without shadows; ``segmentation``:
        per pixel ``uid + ((link + 1) << 24)`` (else PyBullet's default mask)."""
        extra = {"flags": ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX} if segmentation else {}
        return self.c.getCameraImage(width, height, viewMatrix=view, projectionMatrix=projection,
                                     renderer=ER_TINY_RENDERER, shadow=0, **extra)

    def save_state(self) -> int:
        """Snapshot of every body's state and the contact caches (an in-memory id)."""
        return self.c.saveState()

    def restore_state(self, state_id: int) -> None:
        """Back to a snapshot. Restoring the contact caches too is what makes episodes replay
        bit-for-bit: teleporting bodies alone leaves the solver's warm-start data of the last episode."""
        self.c.restoreState(stateId=state_id)

    def close(self) -> None:
        """Disconnect; safe to call twice."""
        if self.client is not None:
            self.client.disconnect()
            self.client = None
            self.bodies = {}

    def __del__(self):  # a garbage-collected env must not leak its physics server
        try:
            self.close()
        except Exception:
            pass
