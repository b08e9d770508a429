"""Laptop: open the lid.

Task: reach the lid's free edge, grasp it (palm and at least two fingers on the lid) and open it
from its initial 0.2 rad to the object's target angle (DexArt's annotated "middle").

Randomisation (DexArt): nominal position plus U[0, 0.1)^3 m (one-sided, z included), yaw
U[-60, 60] degrees. The laptop is drawn from the split with the env's RNG at every reset.

Progress: 1 - |q - target| / |target - init|: 0 at the start, 1 at the target, negative when the
lid is pushed shut.

Success: progress > 0.95 while in stage 3. The episode then ends (terminated).

Reward terms (``info["reward_terms"]``; the reward is their sum):
    reach        stage 1: -0.1 * min(dist, 0.5), dist = palm-to-grasp-point distance (m)
    contact      stages 2-3: +0.2 while grasping
    arm_contact  stages 2-3: -0.1 per arm link touching the laptop
    progress     stage 3: +1.0 * progress; stages 1-2: +0.5 * progress when progress < 0 (closing)
    bonus        on success: (horizon - t) * 1.2 * progress  (reward="capped": counted up to 0.95;
                 reward="flat": horizon * 1.2 * 0.95 at any step)
    penalty      -0.01 * (action penalty + control penalty), every step
Stages: 1 reach (dist > 0.2 m), 2 contact (close, not grasping), 3 manipulate (grasping).
"""

from __future__ import annotations


from dexart_lite.camera import CameraPose
from dexart_lite.envs import rewards
from dexart_lite.envs.base import DexArtEnv, State
from dexart_lite.registration import SPECS

REACH_THRESHOLD = 0.2  # m
MIN_FINGERS = 2
PALM_REQUIRED = True
CLOSING_WEIGHT = 0.5  # reward per unit of negative progress before the grasp
PENALTY_WEIGHT = 0.01


def lid_progress(s: State) -> float:
    """1 - |q - target| / |target - init| (laptop and toilet)."""
    return 1.0 - abs(s.q - s.obj.joint_target) / abs(s.obj.joint_target - s.obj.joint_init)


class LaptopEnv(DexArtEnv):
    SPEC = SPECS["laptop"]
    CAMERA = CameraPose.look_at(eye=(0.0, 1.0, 0.5), target=(0.0, 0.0, 0.5))
    VIEWER = CameraPose.look_at(eye=(0.45, 0.75, 0.65), target=(-0.15, 0.0, 0.12))
    CROP = (0.1, 1.0, -1.0, 2.0, 0.0047767, 0.6)
    REACH_THRESHOLD, MIN_FINGERS, PALM_REQUIRED, PENALTY_WEIGHT = REACH_THRESHOLD, MIN_FINGERS, PALM_REQUIRED, PENALTY_WEIGHT

    def grasped(self, s: State) -> bool:
        return s.n_fingers >= self.MIN_FINGERS and (s.palm_contact or not self.PALM_REQUIRED)

    def progress(self, s: State) -> float:
        return lid_progress(s)

    def stage(self, s: State) -> int:
        return rewards.reach_stage(s, self.REACH_THRESHOLD, self.grasped(s))

    def is_success(self, s: State) -> bool:
        return self.progress(s) > self.SPEC.success["progress"] and self.stage(s) == 3

    def reward_terms(self, s: State, stage: int, progress: float, success: bool) -> dict[str, float]:
        if stage == 3:
            progress_term = progress
        else:
            progress_term = CLOSING_WEIGHT * progress if progress < 0 else 0.0
        return {
            "reach": rewards.reach(s.dist) if stage == 1 else 0.0,
            "contact": rewards.CONTACT_BONUS * self.grasped(s) if stage >= 2 else 0.0,
            "arm_contact": -rewards.ARM_CONTACT_COST * s.arm_contacts if stage >= 2 else 0.0,
            "progress": progress_term,
            "bonus": self.bonus(s, progress, self.SPEC.success["progress"]) if success else 0.0,
            "penalty": rewards.penalty(s, self.PENALTY_WEIGHT),
        }
