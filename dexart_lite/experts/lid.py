"""The lid grasp's geometry (laptops and toilets); the expert that uses it is in ``laptop.py``."""

from __future__ import annotations

import numpy as np

from dexart_lite.experts.base import Solver
from dexart_lite.experts.controller import hand_shape
from dexart_lite.experts.geometry import Pose, finger_tip, hand_frame


class LidSolver(Solver):
    """Laptop and toilet: the lid grasp's geometry, shared by the lid experts (``FeedbackLidSolver``).

    Lid frame (``PartFrame``): the hinge axis is +y, the closed lid extends toward -x (the free edge
    at the lowest x), q > 0 lifts the free edge; the outer face is +z, the inner face -z.

    The palm faces the lid and the fingers point up from start to end: after the first turn from the
    start pose (about 100 degrees, under 2 s at the 1 rad/s cap) the hand never turns over, and
    palm-forward poses are also the ones that reach farthest (about 0.75 m from the shoulder, which
    the far toilets need at their target; a palm-down grasp over the top edge reaches about 0.6 m).
    The grasp has four parts (the expert's regions):

    1. approach: over to beside the lid (above it when the direct way would sweep through it), down
       to the height of a point under the inner face, the thumb stretched forward from the lower palm;
       then along the edge until the thumb is under its middle (``thumb_pose``).
    2. lift: without turning, the thumb tip follows that point on the lid turned ``LEAD`` further:
       the lid turns up on the thumb until ``wrap_at``.
    3. wrap: the thumb drops off the lid and swings aside, the hand comes over the edge and lays the
       palm on the inner face with the knuckle line just past the free edge (``wrap_pose``, pitched so
       that the thumb's base link, 6 mm proud of the palm, clears the lid), and the fingers curl over
       the edge onto the outer face. Palm and fingertips squeeze the lid: the forces are internal to the
       hand, so every contact carries far more than the 2.5 N that count, whatever the lid's friction
       (a flat hand that only pushes a light toilet lid open stays under 2.5 N: tried, it never counts
       as a grasp).
    4. ride: the hand carries that grasp on the lid turned to a goal angle until the lid is at the
       target. The grasp holds the lid both ways, so a lid that overshot during the lift is pulled back.

    Its first version was a phase machine with step counters (committed ``solve_*`` results up to
    2026-11-25: 1.00 on every toilet), whose students failed (toilet 0.08 / 0.03, laptop 0.00 / 0.00):
    no observation shows a counter. ``FeedbackLidSolver`` is the same grasp as a state-feedback law.
    """

    PALM_FACE = 0.0111  # m: the palm box's palmar face in front of the base_link origin (+x)
    TIP_R = 0.012  # m: fingertip / thumb-tip sphere radius
    # Thumb stretched forward for the lift: joint angles and its tip centre in the palm frame (m).
    # Laptop: 7.5 cm in front of the palm, so the palm stays 4 cm in front of the free edge, clear of
    # a laptop base that reaches up to 2.3 cm beyond the lid. Toilet: 4 cm, so the palm stays 0.24 m
    # or more in front of the robot for the nearest toilets (the arm cannot fold closer at that
    # height); the bowl never reaches beyond the lid.
    THUMB_LIFT = {"laptop": ((0.767, 1.163, 0.597, 1.719), (0.0746, 0.0288, -0.0500)),
                  "toilet": ((0.389, 1.163, 1.382, 1.719), (0.0402, 0.0218, -0.0525))}
    THUMB_ASIDE = (0.263, -0.105, -0.19, 0.0)  # stretched out sideways, 9-15 cm below the knuckles
    D = 0.02  # m: thumb tip this far in from the free edge
    TIP_BELOW = 0.016  # m: thumb tip centre under the inner face
    LEAD = 0.25  # rad: while lifting, follow the lid turned this much further
    WRAP_AT = 1.15  # rad: wrap once the lid is this open (earlier for targets below 1.4)
    PITCH = 0.22  # rad: fingers leaning into the lid, palm bottom away from it
    OVER = 0.004  # m: palm face's upper edge this far past the free edge
    SQUEEZE = 0.008  # m: fingertips aimed this far into the outer face
    WRAP_OPEN = (1.45, 0.0, 0.0)  # MCP, PIP, DIP: straight fingers sticking out over the edge

    def __init__(self, env):
        super().__init__(env)
        lo, hi = self.frame.mesh_bounds
        self.corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        self.edge_x, self.mid_y, self.width = lo[0], 0.5 * (lo[1] + hi[1]), hi[1] - lo[1]
        self.inner_z, self.thickness = lo[2], hi[2] - lo[2]  # thickness: an upper bound near the edge
        thumb, self.thumb_tip = self.THUMB_LIFT[env.CATEGORY]
        self.lift_shape = hand_shape(thumb=thumb)
        # Wrap: the finger curl whose tip lands on the outer face, about 3 cm in from the edge.
        m, p, d = np.meshgrid(np.linspace(1.2, 1.61, 15), np.linspace(0.0, 1.7, 35), np.linspace(0.0, 1.6, 17),
                              indexing="ij")
        tips = np.array([finger_tip(*c) for c in zip(m.ravel(), p.ravel(), d.ravel())])
        depth = self.PALM_FACE + self.thickness + self.TIP_R - self.SQUEEZE
        best = np.argmin(np.abs(tips[:, 0] - depth) + 0.3 * np.abs(tips[:, 1] + 0.03))
        self.wrap_shape = hand_shape(finger=(0.0, m.ravel()[best], p.ravel()[best], d.ravel()[best]),
                                     thumb=self.THUMB_ASIDE)
        self.wrap_open = hand_shape(finger=(0.0, *self.WRAP_OPEN), thumb=self.THUMB_ASIDE)
        # Lift orientation (world, fixed): palm normal along the closed lid's +x made horizontal, fingers up.
        x0 = self.frame.pose(0.0).R[:, 0]
        self.R_lift = hand_frame((x0[0], x0[1], 0.0), (0.0, 0.0, 1.0))
        self.side = 1.0  # come in along the lid frame's +y side (``FeedbackLidSolver.FIXED_SIDE``)
        target = env.objects.active.joint_target
        self.wrap_at = min(self.WRAP_AT, target - 0.25)

    # ------------------------------------------------------------------ poses
    def thumb_pose(self, lid: Pose, side: float = 0.0, off: float = 0.0) -> Pose:
        """Palm pose (world, lift orientation) with the thumb tip under the lid near the edge: ``side``
        m along the edge (lid y), ``off`` m farther from the inner face."""
        tip = lid.apply((self.edge_x + self.D, self.mid_y + side, self.inner_z - self.TIP_BELOW - off))
        return Pose(tip - self.R_lift @ np.asarray(self.thumb_tip), self.R_lift)

    def wrap_pose(self, out: float = 0.0, up: float = 0.0, press: float = 0.002) -> Pose:
        """Palm pose in the lid frame: palm on the inner face, knuckle line past the free edge, fingers
        toward the edge. ``out``: palm off the face (m); ``up``: further past the edge; ``press``: into it."""
        n = np.array([np.sin(self.PITCH), 0.0, np.cos(self.PITCH)])  # palm normal, into the lid
        R = hand_frame(n, (-np.cos(self.PITCH), 0.0, np.sin(self.PITCH)))
        corner = np.array([self.edge_x - self.OVER - up, self.mid_y, self.inner_z + press - out])
        return Pose(corner - R @ np.array([self.PALM_FACE, 0.0, 0.0]), R)
