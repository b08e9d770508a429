"""Reward pieces shared by the tasks, as pure functions of a ``State`` (DexArt's numbers).

Each task's ``reward_terms`` assembles its named terms from these; the reward is their sum.
"""

from __future__ import annotations

import numpy as np

REACH_CAP = 0.5  # m: the reach term saturates beyond this distance
REACH_WEIGHT = 0.1  # per m
CONTACT_BONUS = 0.2  # for a grasp contact
ARM_CONTACT_COST = 0.1  # per arm link (or once, for the bucket) touching the object
BONUS_RATE = 1.2  # terminal bonus per remaining step and unit of progress


def reach(dist: float) -> float:
    """Stage 1: -0.1 per metre between palm and handle, capped at 0.5 m."""
    return -REACH_WEIGHT * min(dist, REACH_CAP)


def action_penalty(qvel: np.ndarray) -> float:
    """0.01 * sum of squared joint speeds (rad/s), each clipped to [-1, 1]."""
    return 0.01 * float(np.sum(np.clip(qvel, -1.0, 1.0) ** 2))


def control_penalty(flange_delta: np.ndarray, commanded_velocity: np.ndarray, control_dt: float) -> float:
    """1e3 * squared error (m^2) between where the flange went and where the twist asked it to go."""
    error = np.asarray(flange_delta) - np.asarray(commanded_velocity) * control_dt
    return 1e3 * float(error @ error)


def penalty(s, weight: float) -> float:
    """The negative penalty term: -weight * (action penalty + control penalty)."""
    return -weight * (action_penalty(s.robot.qvel) + control_penalty(s.flange_delta, s.commanded_velocity, s.control_dt))


def terminal_bonus(s, progress: float, threshold: float, mode: str = "dexart") -> float:
    """Paid once on early success: DexArt's (horizon - t) * 1.2 * progress; reward="capped" counts progress only
    up to ``threshold`` (the progress success needs); reward="flat" pays horizon * 1.2 * threshold at any step."""
    if mode == "flat":
        return s.horizon * BONUS_RATE * threshold
    return (s.horizon - s.t) * BONUS_RATE * (min(progress, threshold) if mode == "capped" else progress)


def reach_stage(s, reach_threshold: float, grasped: bool) -> int:
    """1 (reach) while the palm is farther than ``reach_threshold`` m from the handle,
    2 (contact) until ``grasped``, then 3 (manipulate)."""
    if s.dist > reach_threshold:
        return 1
    return 3 if grasped else 2


# ----------------------------------------------------------------------------- the shaped variant
# reward="shaped" (not DexArt's): DexArt's terms plus these, each in ``info["reward_terms"]``. In stage 2
# (close to the part, not yet grasping) DexArt's reward is flat: nothing rewards forming the grasp or
# moving the part before the grasp counts, so PPO must stumble on the grasp by chance. Every term below
# is a departure from DexArt, paid only in stage 2 and bounded (at most +0.25 + 0.5 per step).
REWARD_MODES = ("dexart", "shaped", "capped", "flat")
SHAPE_TOUCH = 0.05  # per hand group (thumb, index, middle, ring, palm) touching the functional part
SHAPE_REACH = 0.1  # per m between palm and grasp point (DexArt's reach weight, continued into stage 2)
SHAPE_PROGRESS = 0.5  # per unit of progress before the grasp (half of DexArt's stage-3 weight)


def shaping(s, stage: int, progress: float) -> dict[str, float]:
    """The shaped variant's extra terms (zero outside stage 2)."""
    if stage != 2:
        return {"shape_touch": 0.0, "shape_reach": 0.0, "shape_progress": 0.0}
    return {"shape_touch": SHAPE_TOUCH * int(np.sum(s.part_contact)),
            "shape_reach": -SHAPE_REACH * min(s.dist, REACH_CAP),
            "shape_progress": SHAPE_PROGRESS * max(float(progress), 0.0)}


# ----------------------------------------------------------------------------- the capped variant
# reward="capped" (not DexArt's): DexArt's terms, except that the terminal bonus counts progress only up to the
# task's success threshold (faucet: |q| up to 1.5 rad). DexArt's bonus, (horizon - t) * 1.2 * |q|, pays for
# turning the handle further than success needs: on the faucet, PPO policies that succeed 0.6 of the time
# earn the same mean return as an expert that succeeds 0.98 of the time, by succeeding sooner with the handle
# flung to 2.5-2.7 rad instead of 2.0 (benchmarks/results/rl/return_vs_success_faucet.json). Capped, a
# success is worth the same at any angle past the threshold; succeeding sooner still pays more. The laptop
# and toilet (threshold 0.95 of a progress that ends at 1) barely change; the bucket has no terminal bonus.
#
# reward="flat" (not DexArt's): DexArt's terms, except that a success pays a fixed horizon * 1.2 * threshold
# (faucet: 250 * 1.2 * 1.5 = 450), whenever it comes. On the capped reward the bonus, (horizon - t) * 1.8 on the
# faucet, is nearly the whole return (a failure earns ~0), so a policy can trade reliability for speed: capped PPO
# policies succeed 0.78-0.84 of the time at step ~95 and out-earn an expert that succeeds 0.98 of the time at step
# ~132 (benchmarks/results/rl/return_vs_success_faucet_capped.json). Flat, the return is ~450 * success rate: the
# most reliable policy earns the most. Nothing pays for speed; the per-step terms (~10 per faucet episode) even
# pay a little for taking longer.
