"""The faucet expert."""

from __future__ import annotations

import numpy as np

from dexart_lite.experts.base import Solver
from dexart_lite.experts.geometry import Pose, hand_frame


class FaucetSolver(Solver):
    """Faucet: clamp the lever (spoke, blade) between palm and curled fingers and turn the handle.

    Handle frame: the valve axis is +z, q > 0 turns counter-clockwise seen from above; at q = 0 the
    lever (template A), one spoke (B) or one blade (C) points along -x, tilted up by ``lever_tilt``.
    Hand: palm facing down onto the handle top, fingers along the handle frame's +y (across that
    element), which runs along the hand's +y (index side, where the thumb is). The knuckle line is
    ``ACROSS`` beyond the element's centre line, so the fully curled fingers come back under the
    element and press it up against the palm, and the curled thumb pushes on its near side: the
    squeeze is internal to the hand, so palm, fingers and thumb all carry well over the 2.5 N that
    count, whatever the valve friction. Fingers whose curl would hit the column (or find nothing to
    hold) stay straight. The hand then rides the handle frame counter-clockwise: the curled fingers
    push the element with their proximal phalanges, and the wrist's last joint (+-2 pi) unwinds
    from its start at pi instead of running into its limit.
    """

    PALM_FACE = 0.0111  # m: palmar face of the palm box in front of the base_link origin (+x)
    FINGER_SPACING = 0.0435  # m: index / middle / ring along the hand's y
    FINGER_HALF_WIDTH = 0.014  # m
    ACROSS = 0.02  # m: knuckle line beyond the element's centre line (along the fingers)
    PRESS = 0.006  # m: the palm is asked this far into the handle top (contact force)
    LEAD = 0.6  # rad: while turning, ask for the grasp pose of the handle this much further on
    CURL = (1.61, 1.709, 1.618)  # MCP, PIP, DIP at their upper limits: curl until the element stops them
    THUMB = (0.263, 0.6, 1.31, 1.72)  # curled under the palm, tip at about (0.024, 0.039, -0.03) m

    def __init__(self, env):
        super().__init__(env)
        p, template = env.objects.active.params, env.objects.active.template
        tilt = p["lever_tilt"]
        lever = np.array([-np.cos(tilt), 0.0, np.sin(tilt)])  # the held element's direction, handle frame
        # Finger positions along the element (r, m from the valve axis; negative: the opposite
        # spoke or blade of templates B and C). A finger hooks if its curl clears column and hub.
        clear = max(p["col_r"], p["hub_r"]) + self.FINGER_HALF_WIDTH + 0.003
        both_sides = template in ("B", "C")

        def holds(r: float) -> bool:
            return clear <= r <= p["lever_len"] - 0.004 or (both_sides and clear <= -r <= p["lever_len"] - 0.004)

        # Middle finger at r_m; index at r_m + spacing, ring at r_m - spacing. Most hooking fingers
        # first, the index among them if possible; the middle of the best range of r_m.
        options = []
        for r_m in np.arange(0.0, 0.08, 0.0025):
            hooks = [holds(r_m + self.FINGER_SPACING), holds(r_m), holds(r_m - self.FINGER_SPACING)]
            options.append((sum(hooks), hooks[0], r_m, hooks))
        best = max(o[:2] for o in options)
        r_m, self.hooks = [o[2:] for o in options if o[:2] == best][sum(o[:2] == best for o in options) // 2]
        # Hand frame in the handle frame: palm normal perpendicular to the (tilted) element, pointing down.
        fingers, normal = np.array([0.0, 1.0, 0.0]), np.array([-np.sin(tilt), 0.0, -np.cos(tilt)])
        self.R = hand_frame(normal, fingers)
        anchor = r_m * lever  # on the element's centre line, under the middle finger
        # Palm height: the highest point of the handle under the hand's footprint (palm and fingers).
        rel = self.frame.vertices - anchor
        along, across, depth = rel @ self.R[:, 1], rel @ fingers, rel @ normal
        under = (np.abs(along) < 0.06) & (across > self.ACROSS - 0.095) & (across < self.ACROSS + 0.13)
        self.knuckles = anchor + self.ACROSS * fingers + (depth[under].min() - self.PALM_FACE) * normal
        self.normal = normal

    def grasp(self, height: float = 0.0) -> Pose:
        """Palm pose in the handle frame, its face ``height`` above the handle top (< 0: pressed in)."""
        return Pose(self.knuckles - height * self.normal, self.R)

    def shape(self, closed: bool) -> np.ndarray:
        """Hand joint targets: the hooking fingers curled (or straight), the thumb curled once closed."""
        flex = [self.CURL if (closed and hook) else (0.0, 0.0, 0.0) for hook in self.hooks]
        thumb = self.THUMB if closed else (0.263, 0.0, 0.0, 0.0)
        return np.array([0.0, *flex[0], 0.0, *flex[1], 0.0, *flex[2], *thumb])

    def step(self, s) -> np.ndarray:
        handle = self.frame.pose()
        if self.phase == "approach":  # 10 cm above the grasp while the palm turns down (clear of the lever)
            a, err, err_r = self.action(s, handle @ self.grasp(0.10), self.shape(False))
            if (err < 0.03 and err_r < 0.15) or self.phase_steps > 80:
                self.goto("lower")
            return a
        if self.phase == "lower":
            a, err, err_r = self.action(s, handle @ self.grasp(0.025), self.shape(False))
            if (err < 0.01 and err_r < 0.08) or self.phase_steps > 30:
                self.goto("descend")
                self.q_grasp = s.q
            return a
        # From here the grasp is defined at the angle where the hand came down, so that fingers
        # nudging the handle while they close do not drag the hand after it.
        if self.phase == "descend":  # palm onto the handle top
            a, _, _ = self.action(s, self.frame.pose(self.q_grasp) @ self.grasp(-self.PRESS), self.shape(False))
            if s.part_contact[4] or self.phase_steps > 25:
                self.goto("close")
            return a
        if self.phase == "close":  # curl fingers and thumb round the element
            a, _, _ = self.action(s, self.frame.pose(self.q_grasp) @ self.grasp(-self.PRESS), self.shape(True))
            if self.phase_steps > 12:
                self.goto("turn")
            return a
        # turn: ride the handle frame counter-clockwise
        a, _, _ = self.action(s, self.frame.pose(s.q + self.LEAD) @ self.grasp(-self.PRESS), self.shape(True))
        return a
