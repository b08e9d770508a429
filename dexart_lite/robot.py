"""XArm6 + Allegro right hand: the 22-D action interface, proprioception and named link groups.

Action (22-D, each in [-1, 1]; values outside are clipped):

* ``a[0:3]``: linear velocity of ``link6`` (the arm flange), +-1 m/s, world axes.
* ``a[3:6]``: angular velocity of ``link6``, +-1 rad/s, world axes.
  The twist is turned into arm joint velocities by damped least squares on PyBullet's Jacobian,
  ``qdot = J^T (J J^T + 0.05^2 I)^-1 v``, clipped to +-pi rad/s, and tracked by position motors
  whose targets ramp ``q0 + qdot * t`` over the control step. DexArt applies the twist to the
  flange; the rewards measure the Allegro ``base_link`` ("palm"). Without rotation both move alike.
* ``a[6:22]``: absolute targets of the 16 hand joints, mapped linearly from [-1, 1] onto each
  joint's limits (0 = mid-range), tracked by force-capped position motors.

Drives are PyBullet position motors (implicit, constraint-based), so no gravity compensation is
needed: the motor holds its target against gravity up to its force cap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dexart_lite import robot_model
from dexart_lite.sim import Body, BulletSim

ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 7))
HAND_JOINTS = tuple(f"joint_{i}.0" for i in range(16))
ACTION_DIM = len(ARM_JOINTS) + len(HAND_JOINTS)  # 22

# The synergy hand (the env's ``hand="synergy"``; not DexArt's, whose policy sets all 16 joint targets):
# three numbers in [-1, 1] replace the 16 hand entries of the action: "knuckles" bends the MCP joints of
# index, middle and ring together, "curl" their PIP and DIP joints, "thumb" the 4 thumb joints, each
# moving its joints on a straight line from open (-1, the start pose's hand) to closed (+1). Closed:
# the finger flexions at their upper limits (the faucet and laptop experts' curl), the thumb in the lid
# expert's lifting pose (``LidSolver.THUMB_LIFT["laptop"]``); the abductions stay at 0. Knuckles and curl apart
# hold the laptop expert's hook (knuckles bent, fingers straight, then curled over the edge). The idea:
# PPO's noise on 3 numbers closes the hand as a whole, where 16 independent noises give a half-curled
# hand that rarely closes. Measured: the experts projected on these lines keep most of their success
# (benchmarks/experts/synergy_expert.py), and PPO from scratch did not learn more with it (docs/results/ppo.md).
SYNERGIES = ("knuckles", "curl", "thumb")
SYNERGY_OPEN = np.array([0.0] * 12 + [0.263, 0.0, 0.0, 0.0])  # (16,) rad, the start pose's hand
SYNERGY_CLOSED = np.array([0.0, 1.61, 1.709, 1.618] * 3 + [0.767, 1.163, 0.597, 1.719])  # (16,) rad
SYNERGY_OF_JOINT = np.array([0, 0, 1, 1] * 3 + [2] * 4)  # (16,) the synergy that moves each hand joint


def synergy_targets(synergy: np.ndarray) -> np.ndarray:
    """Hand joint targets (16,) rad of the synergy action (3,) in [-1, 1]: open at -1, closed at +1."""
    closure = (np.clip(synergy, -1.0, 1.0)[SYNERGY_OF_JOINT] + 1.0) * 0.5  # (16,) in [0, 1]
    return SYNERGY_OPEN + closure * (SYNERGY_CLOSED - SYNERGY_OPEN)


def synergy_action(targets: np.ndarray) -> np.ndarray:
    """The synergy action (3,) whose targets are nearest to ``targets`` (16,) rad (least squares per
    synergy, clipped to [-1, 1]); ``synergy_targets`` of it reproduces targets on the synergy lines."""
    span = SYNERGY_CLOSED - SYNERGY_OPEN
    out = np.empty(len(SYNERGIES))
    for k in range(len(SYNERGIES)):
        m = SYNERGY_OF_JOINT == k
        closure = float(np.dot(np.asarray(targets)[m] - SYNERGY_OPEN[m], span[m]) / np.dot(span[m], span[m]))
        out[k] = 2.0 * closure - 1.0
    return np.clip(out, -1.0, 1.0)


ARM_FORCE = 500.0  # N*m per arm joint (DexArt's SAPIEN drive limit; "far larger than real")
HAND_FORCE = 10.0  # N*m per hand joint (DexArt's SAPIEN drive limit)
MAX_LINEAR_SPEED = 1.0  # m/s at |a| = 1
MAX_ANGULAR_SPEED = 1.0  # rad/s at |a| = 1
IK_DAMPING = 0.05  # damped-least-squares lambda
MAX_ARM_JOINT_SPEED = np.pi  # rad/s, per-joint clip of the IK solution

# The start pose. DexArt never sets one: its arm starts at SAPIEN's load-time zeros, a wrist
# singularity (q5 = 0, smallest singular value of the flange Jacobian 0). DexPoint's "face front"
# pose (0, 0, 0, pi, pi/2, pi) folds the arm near its base (smallest singular value 0.088, so the
# 0.05 damping eats 24 % of a twist along that direction). dexart_lite starts from the same family
# (palm facing forward, fingers sideways) with the arm raised and extended, found by a grid search
# over q2, q3, q5 for the best-conditioned pose with the palm about 0.4 m ahead and 0.3 m up:
# palm (base_link) at (0.394, -0.045, 0.325) m from the robot base, smallest singular value 0.167.
# The hand starts open: zeros, clamped into the limits (the thumb rotation to 0.263 rad).
ARM_INIT_QPOS = (0.0, -0.4, -0.4, np.pi, 1.0, np.pi)

# Link groups (DexArt's contact groups; "palm" is the Allegro base_link, not palm_center).
FINGER_GROUPS = {
    "thumb": ("link_15.0_tip", "link_15.0", "link_14.0"),
    "index": ("link_3.0_tip", "link_3.0", "link_2.0", "link_1.0"),
    "middle": ("link_7.0_tip", "link_7.0", "link_6.0", "link_5.0"),
    "ring": ("link_11.0_tip", "link_11.0", "link_10.0", "link_9.0"),
    "palm": ("base_link",),
}
ARM_LINKS = ("link_base", "link1", "link2", "link3", "link4", "link5", "link6")
# DexArt puts these five in one collision group: they never collide with each other.
NO_SELF_COLLISION = ("base_link", "link_1.0", "link_5.0", "link_9.0", "link_13.0")
PALM_LINK = "base_link"
FLANGE_LINK = "link6"


@dataclass(frozen=True)
class RobotState:
    """One reading of the robot (all world frame)."""

    qpos: np.ndarray  # (22,) rad
    qvel: np.ndarray  # (22,) rad/s
    palm_pos: np.ndarray  # (3,) m, base_link frame origin
    palm_quat: np.ndarray  # (4,) xyzw
    palm_linvel: np.ndarray  # (3,) m/s
    palm_angvel: np.ndarray  # (3,) rad/s
    flange_pos: np.ndarray  # (3,) m, link6 frame origin
    flange_quat: np.ndarray  # (4,) xyzw


class Robot:
    """The arm + hand body in a ``BulletSim``, with the action interface.

    Args:
        sim: the simulation to load into.
        base_position: world position of the arm's base (DexArt puts it at x = -0.5).
        control_dt: seconds per control step (physics dt x frame skip), used by the twist integration.
    """

    def __init__(self, sim: BulletSim, base_position=(0.0, 0.0, 0.0), control_dt: float = 0.04):
        self.sim = sim
        self.control_dt = control_dt
        self.base_position = np.asarray(base_position, dtype=float)
        self.body: Body = sim.load_urdf("robot", robot_model.composed_urdf(), position=tuple(base_position),
                                        fixed_base=True, self_collision=True)
        b = self.body
        self.arm = [b.joint(n) for n in ARM_JOINTS]
        self.hand = [b.joint(n) for n in HAND_JOINTS]
        self.joints = self.arm + self.hand  # (22,) in action order
        if sorted(self.joints) != sorted(b.movable):
            raise RuntimeError("the composed robot URDF does not have exactly the 22 expected joints")
        info = [sim.joint_info(b, j) for j in self.joints]
        self.lower = np.array([i[8] for i in info])
        self.upper = np.array([i[9] for i in info])
        self.palm, self.flange = b.link(PALM_LINK), b.link(FLANGE_LINK)
        self.group_links = {g: [b.link(n) for n in names] for g, names in FINGER_GROUPS.items()}
        self.arm_links = [b.link(n) for n in ARM_LINKS]
        self.link_to_group = {k: g for g, ks in self.group_links.items() for k in ks}
        for i, a in enumerate(NO_SELF_COLLISION):
            for bname in NO_SELF_COLLISION[i + 1 :]:
                sim.disable_collision(b, b.link(a), b.link(bname))
        # The Jacobian is taken at link6's URDF frame origin, expressed in its centre-of-mass frame.
        self._flange_origin_in_com = sim.link_origin_in_com(b, self.flange)
        self.init_qpos = np.clip(np.concatenate([ARM_INIT_QPOS, np.zeros(16)]), self.lower, self.upper)
        self._arm_q0 = np.zeros(6)
        self._arm_qdot = np.zeros(6)
        self.reset()
        self.init_palm_pos = self.read().palm_pos.copy()  # (3,) m, world: the palm at every reset

    # ----------------------------------------------------------------------------- reset
    def reset(self, qpos: np.ndarray | None = None) -> None:
        """Teleport to ``qpos`` (default: the init pose) at rest and hold it."""
        qpos = self.init_qpos if qpos is None else np.asarray(qpos, dtype=float)
        self.sim.reset_joints(self.body, self.joints, qpos)
        self._arm_q0, self._arm_qdot = qpos[:6].copy(), np.zeros(6)
        self.sim.position_motors(self.body, self.joints, qpos.tolist(), [0.0] * 22, [ARM_FORCE] * 6 + [HAND_FORCE] * 16)

    # ----------------------------------------------------------------------------- action
    def hand_targets(self, action_hand: np.ndarray) -> np.ndarray:
        """Map hand actions in [-1, 1] (16,) onto joint targets within the limits (rad)."""
        lo, hi = self.lower[6:], self.upper[6:]
        return lo + (action_hand + 1.0) * 0.5 * (hi - lo)

    def hand_action(self, targets: np.ndarray) -> np.ndarray:
        """Inverse of ``hand_targets``: the action in [-1, 1] that asks for ``targets`` (rad)."""
        lo, hi = self.lower[6:], self.upper[6:]
        return np.clip(2.0 * (np.asarray(targets) - lo) / (hi - lo) - 1.0, -1.0, 1.0)

    def twist_to_joint_velocity(self, twist: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Damped least squares: flange twist (6,) [m/s, rad/s] -> arm joint velocities (6,) rad/s."""
        lin, ang = self.sim.jacobian(self.body, self.flange, self._flange_origin_in_com, q.tolist())
        jac = np.vstack([np.asarray(lin)[:, :6], np.asarray(ang)[:, :6]])  # (6, 6): arm columns only
        jjt = jac @ jac.T + IK_DAMPING**2 * np.eye(6)
        qdot = jac.T @ np.linalg.solve(jjt, twist)
        return np.clip(qdot, -MAX_ARM_JOINT_SPEED, MAX_ARM_JOINT_SPEED)

    def apply_action(self, action: np.ndarray, q: np.ndarray) -> None:
        """Set the motor targets for one control step. ``action`` (22,) is already clipped to [-1, 1]."""
        twist = np.concatenate([action[:3] * MAX_LINEAR_SPEED, action[3:6] * MAX_ANGULAR_SPEED])
        self._arm_q0 = q[:6].copy()
        self._arm_qdot = self.twist_to_joint_velocity(twist, q)
        self.sim.position_motors(self.body, self.hand, self.hand_targets(action[6:]).tolist(), [0.0] * 16,
                                 [HAND_FORCE] * 16)

    def track_arm(self, t: float) -> None:
        """Arm motor targets at ``t`` seconds into the control step: the ramp q0 + qdot * t."""
        self.sim.position_motors(self.body, self.arm, (self._arm_q0 + self._arm_qdot * t).tolist(),
                                 self._arm_qdot.tolist(), [ARM_FORCE] * 6)

    # ----------------------------------------------------------------------------- reading
    def read(self) -> RobotState:
        q, qd = self.sim.joint_states(self.body, self.joints)
        pos, quat, lin, ang = self.sim.link_frames(self.body, [self.palm, self.flange], velocity=True)
        return RobotState(qpos=q, qvel=qd, palm_pos=pos[0], palm_quat=quat[0], palm_linvel=lin[0],
                          palm_angvel=ang[0], flange_pos=pos[1], flange_quat=quat[1])
