"""Faucet: turn the handle about 90 degrees.

Task: reach the faucet's handle, grasp it (palm and at least two fingers on it) and turn it by
more than 1.5 rad, either way.

Randomisation (DexArt): the faucet's root is placed at its nominal position plus U[0, 0.1)^3 m
(one-sided, z included) and yawed by U[-90, 90] degrees. The object is drawn from the split with
the env's RNG at every reset.

Success: |q| > 1.5 rad while in stage 3. The episode then ends (terminated).

Reward terms (``info["reward_terms"]``; the reward is their sum):
    reach        stage 1: -0.1 * min(dist, 0.5), dist = palm-to-handle distance (m)
    contact      stages 2-3: +0.2 while grasping (palm + >= 2 fingers on the handle)
    arm_contact  stages 2-3: -0.1 per arm link touching the faucet
    progress     stage 3: +1.0 * |q|
    bonus        on success: (horizon - t) * 1.2 * |q|  (reward="capped": |q| counted up to 1.5 rad;
                 reward="flat": horizon * 1.2 * 1.5 at any step)
    penalty      -0.01 * (action penalty + control penalty), every step
Stages: 1 reach (dist > 0.2 m), 2 contact (close, not grasping), 3 manipulate (grasping).
"""

from __future__ import annotations


from dexart_lite.camera import CameraPose
from dexart_lite.envs import rewards
from dexart_lite.envs.base import DexArtEnv, State
from dexart_lite.registration import SPECS

REACH_THRESHOLD = 0.2  # m
MIN_FINGERS = 2  # finger groups on the handle for a grasp (plus the palm)
SUCCESS_ANGLE = SPECS["faucet"].success["angle"]  # rad (~86 degrees)
PENALTY_WEIGHT = 0.01


class FaucetEnv(DexArtEnv):
    SPEC = SPECS["faucet"]
    CAMERA = CameraPose.look_along(eye=(-0.3, 0.6, 0.4), forward=(0.16, -0.7, -0.35), right=(-1.5, -2.0, 0.0))
    VIEWER = CameraPose.look_at(eye=(0.45, 0.75, 0.65), target=(-0.15, 0.0, 0.12))
    CROP = (0.1, 2.0, -1.0, 1.0, 0.0047767, 0.4)

    def grasped(self, s: State) -> bool:
        return s.n_fingers >= MIN_FINGERS and s.palm_contact

    def progress(self, s: State) -> float:
        return abs(s.q)  # openness, rad

    def stage(self, s: State) -> int:
        return rewards.reach_stage(s, REACH_THRESHOLD, self.grasped(s))

    def is_success(self, s: State) -> bool:
        return abs(s.q) > SUCCESS_ANGLE and self.stage(s) == 3

    def reward_terms(self, s: State, stage: int, progress: float, success: bool) -> dict[str, float]:
        return {
            "reach": rewards.reach(s.dist) if stage == 1 else 0.0,
            "contact": rewards.CONTACT_BONUS * self.grasped(s) if stage >= 2 else 0.0,
            "arm_contact": -rewards.ARM_CONTACT_COST * s.arm_contacts if stage >= 2 else 0.0,
            "progress": progress if stage == 3 else 0.0,
            "bonus": self.bonus(s, progress, SUCCESS_ANGLE) if success else 0.0,
            "penalty": rewards.penalty(s, PENALTY_WEIGHT),
        }
