"""The lid expert of laptops and toilets: the lid grasp of ``LidSolver`` as a memoryless state-feedback law."""

from __future__ import annotations

import numpy as np

from dexart_lite.experts.controller import hand_shape
from dexart_lite.experts.geometry import Pose, pursue
from dexart_lite.experts.lid import LidSolver


class FeedbackLidSolver(LidSolver):
    """``LidSolver``'s grasp as a state-feedback law: the action is a function of the current robot and
    lid state only (no phase, no step counter), so that a student can copy it from observations and
    DAgger's labels agree with each other wherever the student takes the hand.

    The four parts of ``LidSolver``'s grasp become regions of the state:

    * lid below ``wrap_q`` (the lift; ``wrap_q`` is 0.05 rad short of ``LidSolver.wrap_at``): the palm follows a fixed path start -> above beside the lid ->
      down beside it -> thumb under the middle of the free edge (pure pursuit, ``pursue``); once the
      thumb is there (the palm within ``NEAR`` of the thumb pose on the arc of the lid turned 0 to
      ``LEAD`` further), the target is the thumb pose of the lid turned further: the lid turns up on it.
    * lid at ``wrap_q`` or more (the wrap): the palm follows clear (thumb straight down off the inner
      face, hand and thumb still in their lifting pose) -> over the edge, off the inner face -> palm on
      the inner face; the fingers curl once the palm
      is within ``CLOSE_AT`` of the inner-face pose; with the fingers curled (read from the hand's
      joint angles) and the palm within ``HOLD`` of the grasp, the hand rides the lid to its target.
      A grasp lost on the way opens the fingers and the path starts again from where the hand is.

    Tuned for a hand that is not where it was asked to be (a noisy student's): the gates for curling and
    riding are 2.5 and 5 cm wide, the palm aims just short of the inner face, and the fingers close as
    a hook to their joint limits (see the constants). Success under Gaussian action noise of std 0.3 /
    0.5, seen laptops, 3 episodes per object: 0.73 / 0.27 (unseen 0.56 / 0.22), against 0.27 / 0.00
    before these changes (``benchmarks/results/experts/exploration_noise_laptop.json`` and its history).

    ``region`` names the rule that chose the last action ("approach", "lift", "wrap", "close" or
    "ride"), for plots and tests; it is an output, never an input.
    """

    LOOKAHEAD = 0.04  # m
    NEAR = 0.02  # m: the thumb counts as under the edge
    # Gates wide enough for a hand under action noise: with 1.2 cm and 3 cm (the first version) a hand
    # under noise std 0.3 rarely got close enough to curl, and the expert succeeded 0.27 of the time.
    CLOSE_AT = 0.025  # m: palm this near the inner-face pose: curl the fingers
    HOLD = 0.05  # m: palm this near the grasp pose with curled fingers: ride
    # While wrapping, the palm aims 4 mm short of the inner face, not into it: the goal moves with the lid,
    # so a goal inside the lid pushed it open step after step (lids flung past their target under noise).
    PRESS = -0.004  # m
    HOOK = (1.61, 1.709, 1.618)  # rad: MCP, PIP, DIP at their upper limits
    # How far the fingers are curled, 0 (``wrap_open``) to 1 (``wrap_shape``), read from the joint angles
    # (fingers stopped by the lid reach 0.85-0.99 of the commanded curl): past CURLING the hand goes on
    # closing, past CURLED it rides.
    CURLING, CURLED = 0.2, 0.5
    FIXED_SIDE = {"laptop": 1.0, "toilet": 1.0}  # the lid frame's +y side, whatever the placement
    # How far ahead of the lid the thumb leads it while lifting (rad). Toilet lids (density 50) are light:
    # at the laptop's 0.25 they fly past the wrap and the grasp misses them more often (seen toilets,
    # 3 episodes each: 0.90 at 0.25, 0.94 at 0.15).
    LIFT_LEAD = {"laptop": 0.25, "toilet": 0.15}

    def __init__(self, env):
        super().__init__(env)
        self.start = env.robot.init_palm_pos  # the reset pose: the same for every episode
        # Always come in along the same side of the lid: ``LidSolver`` picks the side nearer the robot's
        # centre line, which flips across the middle of DexArt's position randomisation (laptops at
        # y = -0.05 + U[0, 0.1) m): a student regressing on both would average them and go neither way.
        self.side = self.FIXED_SIDE.get(env.CATEGORY, self.side)
        self.LEAD = self.LIFT_LEAD.get(env.CATEGORY, self.LEAD)
        self.region = "approach"
        self.wrap_q = self.wrap_at - 0.05  # lid angle (rad) from which the wrap takes over
        # Fingers curled to their joint limits (a hook that closes until it meets the lid) instead of
        # ``LidSolver``'s computed curl whose tips land 3 cm in from the edge: the hook holds the lid
        # wherever the knuckles end up past the edge, and a joint target at its limit is one that
        # action noise can only push one way (the env clips it).
        self.wrap_shape = hand_shape(finger=(0.0, *self.HOOK), thumb=self.THUMB_ASIDE)
        self._flex = np.r_[1:4, 5:8, 9:12]  # MCP, PIP, DIP of index, middle, ring among the 16 hand joints
        self._open, self._curl = (float(np.mean(shape[self._flex])) for shape in (self.wrap_open, self.wrap_shape))

    def curl(self, s) -> float:
        """The fingers' curl, 0 open to 1 closed (mean flexion of index, middle and ring)."""
        return (float(np.mean(s.robot.qpos[6:][self._flex])) - self._open) / (self._curl - self._open)

    def step(self, s) -> np.ndarray:
        q, target = s.q, s.obj.joint_target
        lid = self.frame.pose()
        palm = s.robot.palm_pos
        if q < self.wrap_q:
            arc = [self.thumb_pose(self.frame.pose(q + d)).p for d in np.linspace(0.0, self.LEAD, 5)]
            if min(np.linalg.norm(p - palm) for p in arc) < self.NEAR:  # lift: the lid turns up on the thumb
                self.region = "lift"
                q_goal = q + np.clip(self.wrap_at + 0.05 - q, 0.03, self.LEAD)
                a, _, _ = self.action(s, self.thumb_pose(self.frame.pose(q_goal)), self.lift_shape)
                return a
            self.region = "approach"
            beside = self.thumb_pose(lid, side=self.side * (0.5 * self.width + 0.075))
            top = max(lid.apply(c)[2] for c in self.corners)
            above = beside.p + np.array([0.0, 0.0, max(0.0, top + 0.125 - beside.p[2])])
            goal, _ = pursue([self.start, above, beside.p, self.thumb_pose(lid).p], palm, self.LOOKAHEAD)
            a, _, _ = self.action(s, Pose(goal, self.R_lift), self.lift_shape)
            return a
        grasp = lid @ self.wrap_pose(press=self.PRESS)
        err, curl = float(np.linalg.norm(grasp.p - palm)), self.curl(s)
        if err < self.HOLD and curl > self.CURLED:  # ride the grasp to the target
            self.region = "ride"
            q_goal = q + np.clip(1.5 * (target - q), -0.25, 0.25)
            a, _, _ = self.action(s, self.frame.pose(q_goal) @ self.wrap_pose(), self.wrap_shape, speed=0.5)
            return a
        if err < self.CLOSE_AT or (err < self.HOLD and curl > self.CURLING):  # curl the fingers over the edge
            self.region = "close"
            a, _, _ = self.action(s, grasp, self.wrap_shape)
            return a
        self.region = "wrap"
        # From the lifting pose straight down off the inner face first (a thumb dragged up past the
        # edge flings the lid open), then over the edge and onto the inner face, slowly near the lid.
        path = [self.thumb_pose(lid).p, self.thumb_pose(lid, off=0.05).p, (lid @ self.wrap_pose(out=0.05, up=0.03)).p,
                grasp.p]
        goal, segment = pursue(path, palm, self.LOOKAHEAD)
        # Hand and thumb keep their lifting pose until the thumb is clear: turning the hand or swinging
        # the thumb aside under the lid would fling it open.
        rotation, hand = (self.R_lift, self.lift_shape) if segment == 0 else (grasp.R, self.wrap_open)
        a, _, _ = self.action(s, Pose(goal, rotation), hand, speed=1.0 if err > 0.05 else 0.5)
        return a
