"""Toilet: open the lid.

The laptop task with other numbers (DexArt's toilet env is a copy of its laptop env): the same
progress, stages, success and reward terms as ``laptop.py``, except that

* the reach stage ends at 0.1 m (not 0.2 m) from the lid's grasp point;
* a grasp needs at least two fingers on the lid, the palm is not required;
* the lid starts 0.25 rad open (``joint_init`` of the objects);
* the penalty weight is 0.005;
* the robot stands on a 0.4 m pedestal, and the randomisation is wider: U[0, 0.2)^3 m and yaw
  U[-45, 45] degrees.

DexArt's toilet lid and seat shapes share a collision group so they never collide; here only that
pair is excluded (see ``ArticulatedObjects``), so the palm cannot pass through the lid.

Reward terms: reach, contact, arm_contact, progress, bonus, penalty (see ``laptop.py``).
"""

from __future__ import annotations


from dexart_lite.camera import CameraPose
from dexart_lite.envs.laptop import LaptopEnv
from dexart_lite.registration import SPECS

REACH_THRESHOLD = 0.1  # m
MIN_FINGERS = 2
PALM_REQUIRED = False
PENALTY_WEIGHT = 0.005


class ToiletEnv(LaptopEnv):
    SPEC = SPECS["toilet"]
    PEDESTAL = ((-0.5, 0.0, 0.2), (0.1, 0.2, 0.2))  # centre, half extents (m)
    CAMERA = CameraPose.look_at(eye=(0.0, 1.0, 0.5), target=(0.0, 0.0, 0.5))
    VIEWER = CameraPose.look_at(eye=(0.7, 1.0, 1.0), target=(-0.1, 0.0, 0.35))
    CROP = (0.1, 2.0, -2.0, 2.0, -0.3, 0.8)
    REACH_THRESHOLD, MIN_FINGERS, PALM_REQUIRED, PENALTY_WEIGHT = REACH_THRESHOLD, MIN_FINGERS, PALM_REQUIRED, PENALTY_WEIGHT
