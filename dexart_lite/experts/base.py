"""What every expert shares: the functional part's frame (``PartFrame``) and the ``Solver`` base class
(one state machine per task, acting through the same 22-D action as a learned policy)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from dexart_lite.articulated import PART_LINK
from dexart_lite.experts.controller import OPEN, PalmController
from dexart_lite.experts.geometry import Pose, rot_axis
from dexart_lite.pointcloud import quat_to_matrix
from dexart_lite.registration import EXPERT_PRIVILEGED, privileged_vector



# ----------------------------------------------------------------------------- the part's frame
class PartFrame:
    """The functional part's pose, now and at other joint angles, and its extent in its own frame."""

    def __init__(self, env):
        import yourdfpy  # local import: only the solvers read object URDFs

        self.env = env
        path = Path(env.objects.active.urdf_path)
        urdf = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False)
        joint = next(j for j in urdf.robot.joints if j.type == "revolute")
        self.axis_local = np.asarray(joint.axis, float)  # joint axis in the part frame
        mesh = trimesh.load(path.parent / urdf.link_map[joint.child].visuals[0].geometry.mesh.filename, force="mesh")
        self.mesh_bounds = mesh.bounds  # (2, 3), part frame, m
        self.vertices = np.asarray(mesh.vertices)  # (N, 3), part frame, m

    def pose(self, q: float | None = None) -> Pose:
        """World pose of the part frame at joint angle ``q`` (default: now)."""
        env = self.env
        pos, quat = env.sim.link_frames(env.objects.body, [PART_LINK])
        now = Pose(pos[0], quat_to_matrix(quat[0]))
        if q is None:
            return now
        axis_world = now.R @ self.axis_local
        return Pose(now.p, rot_axis(axis_world, q - env.state.q) @ now.R)


# ----------------------------------------------------------------------------- the solvers
class Solver:
    """Base of the per-task state machines. ``act(state) -> action (22,)``."""

    def __init__(self, env):
        self.env = env
        self.frame = PartFrame(env)
        self.palm = PalmController()
        self.phase, self.phase_steps = "approach", 0
        self.hand = OPEN.copy()

    def goto(self, phase: str) -> None:
        self.phase, self.phase_steps = phase, 0

    def action(self, state, target: Pose, hand: np.ndarray, speed: float = 1.0) -> tuple[np.ndarray, float, float]:
        twist, err_p, err_r = self.palm(state, target, speed)
        return np.concatenate([twist, self.env.robot.hand_action(hand)]), err_p, err_r

    def act(self, state) -> np.ndarray:
        self.phase_steps += 1
        return self.step(state)

    def privileged(self, state) -> np.ndarray:
        """What the expert knows and the student must see in its point cloud: registration.EXPERT_PRIVILEGED,
        ``(PRIVILEGED_DIM,)`` float32 (the part's frame is its mesh's, ``PartFrame``). Distillation uses it as
        an auxiliary target."""
        part = self.frame.pose()
        base = np.asarray(self.env.ROBOT_BASE, float)
        return privileged_vector(EXPERT_PRIVILEGED, part_pos=part.p - base, part_rot=part.R[:, :2].T, joint=state.q,
                                 joint_target=state.obj.joint_target, part_bounds=self.frame.mesh_bounds,
                                 grasp_pos=state.handle_pos - base).astype(np.float32)

    def step(self, state) -> np.ndarray:
        raise NotImplementedError
