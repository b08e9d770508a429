"""Bucket: lift the bucket by its handle (the bail).

Task: reach the bail, which lies on its side, hook at least three fingers under it, raise it
upright and lift the free-standing bucket more than 0.25 m.

Randomisation (DexArt): nominal position plus U[0, 0.05)^3 m (one-sided, z included: the bucket
may drop a few centimetres at the start); no yaw noise. Drawn from the split with the env's RNG.

Progress: 1 - |q - target| / |init - target| (0 with the bail lying, 1 upright).

Success: progress > 0.7 and the body lifted more than 0.25 m above its reset height, at any step.
There is no early termination (as in DexArt), so the bucket may be dropped after a success.

Reward terms (``info["reward_terms"]``; the reward is their sum):
    palm_up      +0.2 * z-component of the palm normal (palm facing up helps to hook the bail)
    base_touch   -0.2 * (hand groups touching the bucket body) / 5
    reach        stage 1: -0.1 * min(dist, 0.5)
    contact      stages 2-3: +0.2 while >= 3 fingers touch the bail
    arm_contact  stages 2-3: -0.1 if any arm link touches the bucket (a boolean, unlike the others)
    stability    stage 2: -0.01 * (|v_body| + |w_body|)
    progress     stages 2-3: +0.5 * progress + 0.2 * progress * (groups touching the bail) / 5
    lift         stage 3, while lifted < 0.3 m: +100 * (palm rise this step, m) + 10 * lift / 0.3
    penalty      -0.1 * (action penalty + control penalty)
Stages: 1 reach (dist > 0.2 m), 2 contact (fewer than 3 fingers on the bail or progress < 0.5),
3 manipulate.

Deviation from DexArt (``dexart-original.md`` quirk 3): DexArt computes palm_up and base_touch and
then overwrites them in stage 1; here they are paid in every stage.
"""

from __future__ import annotations

import numpy as np

from dexart_lite.camera import CameraPose
from dexart_lite.envs import rewards
from dexart_lite.envs.base import DexArtEnv, State
from dexart_lite.registration import SPECS

REACH_THRESHOLD = 0.2  # m
MIN_FINGERS = 3  # of thumb, index, middle, ring on the bail
STAGE3_PROGRESS = 0.5
SUCCESS_PROGRESS = SPECS["bucket"].success["progress"]
SUCCESS_LIFT = SPECS["bucket"].success["lift"]  # m
LIFT_CAP = 0.3  # m
PENALTY_WEIGHT = 0.1


def lift(s: State) -> float:
    """Height gained by the bucket body since the reset, m (never negative)."""
    return max(float(s.base_pos[2] - s.base_pos_at_reset[2]), 0.0)


class BucketEnv(DexArtEnv):
    SPEC = SPECS["bucket"]
    PEDESTAL = ((-0.5, 0.0, 0.15), (0.1, 0.2, 0.15))  # centre, half extents (m)
    CAMERA = CameraPose.look_at(eye=(0.0, 1.0, 0.5), target=(0.0, 0.0, 0.5))
    VIEWER = CameraPose.look_at(eye=(0.55, 0.9, 0.8), target=(-0.15, 0.0, 0.2))
    CROP = (0.1, 2.0, -2.0, 2.0, -0.29, 0.4)
    TERMINATE_ON_SUCCESS = False
    # A fresh simulation every episode: the light free-floating bucket resting on the table is the one
    # object that still felt the robot's contact caches of the previous episode (~1e-6 m within 50
    # steps after an 80-step episode, DexArtEnv.reset); a build costs ~0.07 s, ~5 % of an episode.
    REBUILD_EVERY = 1
    EXTRA_STATE = 1

    def extra_state(self, s: State) -> list[float]:
        return [float(s.palm_x_axis[2])]  # palm-up, as DexArt's bucket state

    def grasped(self, s: State) -> bool:
        return s.n_fingers >= MIN_FINGERS

    def progress(self, s: State) -> float:
        return 1.0 - abs(s.q - s.obj.joint_target) / abs(s.obj.joint_init - s.obj.joint_target)

    def stage(self, s: State) -> int:
        return rewards.reach_stage(s, REACH_THRESHOLD, self.grasped(s) and self.progress(s) >= STAGE3_PROGRESS)

    def is_success(self, s: State) -> bool:
        return self.progress(s) > SUCCESS_PROGRESS and lift(s) > SUCCESS_LIFT

    def reward_terms(self, s: State, stage: int, progress: float, success: bool) -> dict[str, float]:
        touched = s.part_contact.sum() / len(s.part_contact)
        lifted = lift(s)
        return {
            "palm_up": 0.2 * float(s.palm_x_axis[2]),
            "base_touch": -0.2 * s.body_contact.sum() / len(s.body_contact),
            "reach": rewards.reach(s.dist) if stage == 1 else 0.0,
            "contact": rewards.CONTACT_BONUS * self.grasped(s) if stage >= 2 else 0.0,
            "arm_contact": -rewards.ARM_CONTACT_COST * (s.arm_contacts > 0) if stage >= 2 else 0.0,
            "stability": -0.01 * (np.linalg.norm(s.base_linvel) + np.linalg.norm(s.base_angvel)) if stage == 2 else 0.0,
            "progress": 0.5 * progress + 0.2 * progress * touched if stage >= 2 else 0.0,
            "lift": 100 * (s.robot.palm_pos[2] - s.palm_z_prev) + 10 * lifted / LIFT_CAP
            if stage == 3 and lifted < LIFT_CAP else 0.0,
            "penalty": rewards.penalty(s, PENALTY_WEIGHT),
        }
