"""The bucket experts: ``BucketSolver`` (fingertip hook) and ``OverhandBucketSolver`` (overhand cage)."""

from __future__ import annotations

import numpy as np

from dexart_lite.experts.base import Solver
from dexart_lite.experts.controller import PalmController, hand_shape
from dexart_lite.experts.geometry import TUCKED_THUMB, Pose, finger_tip, hand_frame, thumb_reaching
from dexart_lite.pointcloud import quat_to_matrix


class BailSolver(Solver):
    """What the bucket experts share: the bail's grip tube (its apex) and hand targets that move at most
    ``RATE`` rad per control step (a light bail flies off a finger that snaps shut)."""

    RATE = 0.08  # rad per control step: largest change of a hand joint target

    def __init__(self, env):
        super().__init__(env)
        self.apex_local = np.asarray(env.objects.active.grasp_point, float)  # tube centre at q = 0, bail frame
        self.hand_now: np.ndarray | None = None  # the rate-limited hand targets (16,) rad

    def action(self, state, target: Pose, hand: np.ndarray, speed: float = 1.0):
        """As ``Solver.action``, with the hand joint targets moving at most ``RATE`` per step."""
        hand = np.asarray(hand, float)
        self.hand_now = hand.copy() if self.hand_now is None else self.hand_now + np.clip(
            hand - self.hand_now, -self.RATE, self.RATE)
        return super().action(state, target, self.hand_now, speed)

    def apex(self, q: float | None = None) -> np.ndarray:
        """World position of the tube centre at the apex, at bail angle ``q`` (default: now)."""
        return self.frame.pose(q).apply(self.apex_local)


class BucketSolver(BailSolver):
    """Bucket: lift the lying bail on hooked fingertips, close a fist round it, lift the bucket.

    Bail frame (``PartFrame``): the pivot line is +y, q = 0 upright, q = -pi/2 lying toward the
    robot (the apex toward -x); the grasp point is the apex (centre of the grip tube) at q = 0.
    Hand: palm facing +x (toward the bucket) on the robot side of the bail, fingers hanging down,
    spread along the tube. Coordinates "in the palm frame" below: x_h forward (palmar, +x world),
    z_h down the fingers (-z world).

    The lying bail hugs the wall (0.6-1.8 cm of air between tube and wall, less than a finger is
    thick), so no finger can get round it; and the bail weighs 3-15 g and swings freely, so any
    quick touch flicks it over. Hence, with rate-limited finger targets throughout:

    1. approach, lower: the straight fingers come down beside the tube (robot side), tips below it.
    2. hook: the distal phalanges bend toward +x until the fingertips sit under the tube's outer
       half (a J; the tip stays clear of the wall).
    3. raise: the hand follows the apex up its circle (orientation fixed), slowing down, to ``q_mid``
       (the bail leaning back onto the fingers, short of upright, where it would topple over). By
       then the tube is above the rim, and the fingers hang inside it.
    4. slide: straight fingers, the hand slides down along the tube until the tube is just above
       the knuckle line.
    5. fist: the proximal phalanges swing up under the tube (MCP 90 degrees: a shelf), then the
       medial ones up beyond it (PIP 90 degrees: a wall), and the thumb comes down on top: the tube
       is boxed in by palm, shelf, wall and thumb.
    6. lift: straight up ``LIFT``; the bucket hangs from the fist with the bail upright.
    """

    GAP = 0.003  # m: finger's palmar face to the tube while hooking and sliding
    DELTA = -0.002  # m: fingertip centre this far (x) from the tube centre (toward the robot)
    PUSH = 0.003  # m: hooked tips aimed this far up into the tube
    LEAD = 0.4  # rad: while raising, follow the apex turned this much further
    SPEED = 0.5  # of the palm controller's speed caps while raising
    SLIDE_RATE = 0.008  # m per control step
    FIST_Z = -0.008  # m: tube centre this far above the knuckle line (z_h) for the fist
    FIST = (1.57, 1.57, 0.6)  # MCP, PIP, DIP
    THUMB_Y = 0.015  # m: thumb tip beside the middle finger
    THUMB_SQUEEZE = 0.004  # m: thumb tip aimed this far into the tube's top
    LIFT = 0.36  # m: above the fist position (success needs 0.25 m of body lift)
    LIFT_RATE = 0.007  # m per control step

    def __init__(self, env):
        super().__init__(env)
        p = env.objects.active.params
        rho = p["tube_r"]
        self.R = hand_frame(normal=(1, 0, 0), fingers=(0, 0, -1))
        self.c = rho + 0.0098 + self.GAP  # x_h of the tube centre: just in front of the fingers
        # Hook: bend only the DIP, so that the tip centre lands DELTA from the tube centre.
        bends = np.linspace(0.0, 1.6, 161)
        tips = np.array([finger_tip(0.0, 0.0, b) for b in bends])
        k = int(np.argmin(np.abs(tips[:, 0] - (self.c + self.DELTA))))
        self.dip = bends[k]
        rise = np.sqrt((0.012 + rho) ** 2 - self.DELTA ** 2)  # tube centre above the tip centre
        self.hook_z = tips[k][1] - rise + self.PUSH  # z_h of the tube centre while hooked
        # Stop raising where the fingers hanging from the tube still clear the rim: the outer corners
        # of index and ring (5.75 cm either side of the middle finger) inside the rim's inner edge.
        r_in = p["radius"] * p["taper"] - 0.003  # A/B: round rim; C (square) has more room
        x_clear = np.sqrt(max((r_in - 0.003) ** 2 - 0.0575 ** 2, 0.0))
        bail_r = float(np.linalg.norm(self.apex_local))
        self.q_mid = -float(np.clip(np.arcsin(np.clip((x_clear - self.c - 0.0098) / bail_r, -1, 1)), 0.15, 0.35))
        self.thumb = thumb_reaching((self.c, self.THUMB_Y, self.FIST_Z - rho - 0.012 + self.THUMB_SQUEEZE))

    def palm_at(self, tube, x_h: float, z_h: float, up: float = 0.0) -> Pose:
        """Palm pose with the tube centre ``tube`` (world) at (x_h, 0, z_h) in the palm frame."""
        return Pose(np.asarray(tube) - self.R @ np.array([x_h, 0.0, z_h]) + np.array([0.0, 0.0, up]), self.R)

    def shape(self, finger=(0.0, 0.0, 0.0), thumb=TUCKED_THUMB) -> np.ndarray:
        return hand_shape(finger=(0.0, *finger), thumb=thumb)

    def step(self, s) -> np.ndarray:
        tube = self.apex()
        if self.phase == "approach":  # above and behind the hook position
            target = self.palm_at(tube, self.c, self.hook_z, up=0.06)
            a, err, err_r = self.action(s, Pose(target.p - np.array([0.02, 0.0, 0.0]), self.R), self.shape())
            if (err < 0.02 and err_r < 0.1) or self.phase_steps > 80:
                self.goto("lower")
            return a
        if self.phase == "lower":  # straight fingers down beside the tube
            a, err, err_r = self.action(s, self.palm_at(tube, self.c, self.hook_z), self.shape())
            if (err < 0.005 and err_r < 0.05) or self.phase_steps > 40:
                self.goto("hook")
            return a
        hook = self.shape((0.0, 0.0, self.dip))
        if self.phase == "hook":  # fingertips under the tube
            a, _, _ = self.action(s, self.palm_at(tube, self.c, self.hook_z), hook)
            if self.phase_steps > 8:
                self.goto("raise")
            return a
        if self.phase == "raise":  # carry the apex up its circle to q_mid, slowing down
            slow = float(np.clip((self.q_mid - s.q) / 0.6, 0.2, 1.0))
            goal = self.palm_at(self.apex(min(s.q + self.LEAD, self.q_mid)), self.c, self.hook_z)
            a, err, _ = self.action(s, goal, hook, speed=self.SPEED * slow)
            if s.q > self.q_mid - 0.1 and err < 0.01:
                self.goto("slide")
                self.tube_ref, self.z_h = self.apex(self.q_mid), self.hook_z
            return a
        if self.phase == "slide":  # down along the tube until it is by the knuckles
            self.z_h = max(self.z_h - self.SLIDE_RATE, self.FIST_Z)
            a, err, _ = self.action(s, self.palm_at(self.tube_ref, self.c, self.z_h), self.shape(), speed=0.5)
            if self.z_h <= self.FIST_Z and err < 0.005:
                self.goto("fist")
            return a
        fist = self.shape(self.FIST, self.thumb)
        if self.phase == "fist":  # shelf, then wall, then thumb on top
            shape = fist
            if self.phase_steps < 12:
                shape = self.shape((self.FIST[0], 0.0, 0.0) if self.phase_steps < 8 else self.FIST)
            a, _, _ = self.action(s, self.palm_at(self.tube_ref, self.c, self.FIST_Z), shape, speed=0.5)
            if self.phase_steps > 22:
                self.goto("lift")
            return a
        up = min(self.phase_steps * self.LIFT_RATE, self.LIFT)
        a, _, _ = self.action(s, self.palm_at(self.tube_ref, self.c, self.FIST_Z, up=up), fist, speed=0.5)
        return a


class OverhandBucketSolver(BailSolver):
    """Bucket, overhand: come down on the lying tube from above, curl the fingers round its outer side and
    under it, carry it up its circle in the closed hand, turn the hand under it, close the knuckles and lift.

    Hand: palm down, fingers pointing toward the robot over the tube's outer side, tilted ``ALPHA`` below
    the horizontal so that the palm's wrist end rises over the rim. The back of the hand is on the flange,
    so the arm stays above the hand at every bucket height (a palm-up scoop needs the flange below the
    palm: out of reach under ~0.17 m).
    Coordinates "in the palm frame": x_h palmar (down), z_h along the fingers.

    Why this grasp (``BucketSolver`` hooks the fingertips under the tube and carries the bail up on them;
    under exploration noise the 3-15 g bail leaves the tips and topples over the top): the closing fingers
    themselves scoop the tube up off the wall and press it into the crease under the knuckles, so from
    the first raise the tube is held on three sides (palm above, fingers on its outer side and below) and
    the bail's weight leans it into the fingers while it is short of upright; the thumb closes the fourth
    side before the bucket leaves the floor. The raise stops at
    ``QTOP`` from upright (success needs |q| < 0.47 rad); the lift swings the bail upright by itself.

    Closed loop: every step reads where the tube is in the palm frame. A close that did not cage the
    tube, a raise or a lift that lost it, or a descent that does not arrive goes back to the approach
    above wherever the tube now is; no step counter decides a success. A bail flung over the top to
    the far side is not recovered: the mirrored grasp needs the hand turned half round about the
    vertical, and the differential IK runs joint 6 into its 2 pi limit on the way.

    1. approach: open hand 5 cm above the grasp pose of the tube as it is now.
    2. descend: onto the tube, fingers straight, until the tube is within ``TOL`` of (XC, ZC).
    3. close: curl to ``SQUEEZE``; the fingertips lift the tube into the crease (caged, or regrasp).
    4. raise: carry the tube up its circle to ``QTOP``, the tube kept where it sits in the hand.
    5. lift: close the thumb on the tube's wrist side (the cage's open side, where the bail pulls the tube
       once the bucket hangs), then the knuckles under it (``CARRY``; closed first, they push the tube out
       through that side), turning the hand to ``ALPHA_LIFT`` meanwhile, then straight up ``LIFT``.
    """

    RATE = 0.15  # rad per control step: the hand may close faster here, the tube is caged as it closes
    GAIN = 10.0  # 1/s: palm position gain (the base controller's 6 lets noise drift the palm further)
    MAX_SPEED, FINE_SPEED = 0.35, 0.5  # m/s: the palm's speed cap; its fraction near the tube
    ALPHA, ALPHA_LIFT = 0.35, 0.6  # rad: fingers below the horizontal while grasping, and for the lift
    TURN_RATE = 0.04  # rad per control step while turning the hand for the lift
    OPEN = (0.0, 0.0, 0.0)  # MCP, PIP, DIP while coming down
    SQUEEZE = (0.2, 1.6, 1.4)  # the cage: medial on the tube's outer side, distal under it
    CARRY = (1.2, 1.2, 1.0)  # the knuckles closed under the crease for the lift
    XC, ZC = 0.03, 0.05  # m: tube centre in the palm frame where the fingers close
    HELD = ((0.0, 0.065), (-0.06, 0.06), (-0.05, 0.06))  # m: x_h, y_h, z_h box of a tube in the hand
    CARRY_BOX = ((0.015, 0.0, 0.015), (0.035, 0.0, 0.05))  # m: where the hand keeps a held tube (the crease)
    TOL = 0.012  # m: descent arrived
    LEAD = 0.3  # rad: while raising, follow the tube turned this much further
    QTOP = 0.5  # rad from upright: end of the raise, the bail still leaning on the fingers
    THUMB_FIRST, LIFT_AFTER = 6, 14  # control steps of the lift: the thumb alone closes; the hand starts rising
    THUMB_PRESS = 0.003  # m: the thumb's target this far into the tube
    LIFT, LIFT_RATE = 0.36, 0.007  # m, m per control step (success needs 0.25 m of body lift)

    def __init__(self, env):
        super().__init__(env)
        self.palm = PalmController(gain=self.GAIN, max_speed=self.MAX_SPEED)
        # set when the lift starts: the tube's start (world), where it sits in the hand, the thumb's closing targets
        self.top = self.hold = self.thumb = None

    def hand_rotation(self, alpha: float) -> np.ndarray:
        """Palm orientation (3, 3): palm down, fingers toward the robot, ``alpha`` rad below the horizontal."""
        up = self.frame.pose(0.0).R  # the bail's frame upright: x away from the robot, z up
        return hand_frame(normal=up @ np.array([np.sin(alpha), 0.0, -np.cos(alpha)]),
                          fingers=up @ np.array([-np.cos(alpha), 0.0, -np.sin(alpha)]))

    def palm_at(self, tube, x_h: float, z_h: float, alpha: float | None = None, up: float = 0.0) -> Pose:
        """Palm pose (fingers ``alpha`` below the horizontal, default ``ALPHA``) with the tube centre
        ``tube`` (world) at (x_h, 0, z_h) in the palm frame, raised by ``up`` m."""
        R = self.hand_rotation(self.ALPHA if alpha is None else alpha)
        return Pose(np.asarray(tube) - R @ np.array([x_h, 0.0, z_h]) + np.array([0.0, 0.0, up]), R)

    def tube_in_palm(self, s) -> np.ndarray:
        """The tube centre now, (3,) m in the palm frame."""
        return quat_to_matrix(s.robot.palm_quat).T @ (self.apex() - s.robot.palm_pos)

    def held(self, s) -> bool:
        return all(lo < v < hi for v, (lo, hi) in zip(self.tube_in_palm(s), self.HELD))

    @staticmethod
    def shape(finger, thumb=None) -> np.ndarray:
        """Hand targets (16,): index, middle and ring at (MCP, PIP, DIP) ``finger``, the thumb at ``thumb``
        (default: hand_shape's, out of the way)."""
        thumb = {} if thumb is None else {"thumb": thumb}
        return hand_shape(finger=(0.0, *finger), **thumb)

    def step(self, s) -> np.ndarray:
        tube = self.apex()
        if self.phase == "approach":
            a, err, err_r = self.action(s, self.palm_at(tube, self.XC + 0.05, self.ZC), self.shape(self.OPEN))
            if err < 0.02 and err_r < 0.15:
                self.goto("descend")
            return a
        if self.phase == "descend":
            goal = self.palm_at(tube, self.XC, self.ZC)
            a, _, _ = self.action(s, goal, self.shape(self.OPEN), speed=self.FINE_SPEED)
            t = self.tube_in_palm(s)
            if np.hypot(t[0] - self.XC, t[2] - self.ZC) < self.TOL and abs(t[1]) < 0.03:
                self.goto("close")
            elif self.phase_steps > 40:
                self.goto("approach")
            return a
        if self.phase == "close":
            goal = self.palm_at(tube, self.XC, self.ZC)
            a, _, _ = self.action(s, goal, self.shape(self.SQUEEZE), speed=self.FINE_SPEED)
            if self.phase_steps > 16:
                self.goto("raise" if self.held(s) else "approach")
            return a
        if self.phase == "raise":
            t = np.clip(self.tube_in_palm(s), *self.CARRY_BOX)  # carried where it sits, kept in the crease
            q_goal = min(s.q + self.LEAD, -self.QTOP)  # the tube turned LEAD further up, at most to QTOP
            goal = self.palm_at(self.apex(q_goal), t[0], t[2])
            a, err, _ = self.action(s, goal, self.shape(self.SQUEEZE), speed=self.FINE_SPEED)
            if not self.held(s):
                self.goto("approach")
            elif s.q > -self.QTOP - 0.05 and err < 0.025:
                self.goto("lift")
                self.top, self.hold = self.apex(-self.QTOP), t
                rho = self.env.objects.active.params["tube_r"]
                self.thumb = thumb_reaching((t[0] + 0.005, 0.025, t[2] - rho - 0.012 + self.THUMB_PRESS))
            return a
        if not self.held(s) and s.base_pos[2] - s.base_pos_at_reset[2] < 0.03:  # lost before the bucket rose
            self.goto("approach")
        # The thumb closes first, on the tube's wrist side (the cage's one open side: the bail's pull on a
        # lifted bucket points there); only then do the knuckles close under the tube, which would push it
        # out of a cage still open there. The hand turns a little under the tube meanwhile and rises once
        # both are closed.
        alpha = min(self.ALPHA + self.phase_steps * self.TURN_RATE, self.ALPHA_LIFT)
        fingers = self.SQUEEZE if self.phase_steps < self.THUMB_FIRST else self.CARRY
        up = float(np.clip((self.phase_steps - self.LIFT_AFTER) * self.LIFT_RATE, 0.0, self.LIFT))
        goal = self.palm_at(self.top, self.hold[0], self.hold[2], alpha=alpha, up=up)
        a, _, _ = self.action(s, goal, self.shape(fingers, self.thumb), speed=1.0)
        return a
