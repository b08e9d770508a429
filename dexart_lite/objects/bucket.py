"""Procedural buckets: an open-top pail (free body) and a bail (the functional part) on two pivots.

Frames (body frame = object root: origin at the centre of the floor, z = 0 at the bottom; the robot
stands at -x):

* The two pivots sit on the +-y sides of the wall, ``pivot_drop`` below the rim, on short lugs.
* Bail frame = joint frame: origin at the midpoint of the two pivots (on the bucket axis), rpy = 0.
  Joint axis (0, 1, 0): the pivot line itself (an axis perpendicular to the
  pivot line looks plausible but is kinematically wrong).
* q = 0: bail upright (apex straight above the pivot line). q > 0 tips the apex toward +x, q < 0
  toward -x. Limits [-pi/2, pi/2]; init = -pi/2: the bail lies flat on the robot's side (apex toward
  -x); target ("middle") = 0.
* Grasp point = the bail apex at q = 0 (centre line of the grip tube), in the bail frame.
* Friction 0 (DexArt). Densities: body 7800, bail 100 kg/m^3 (DexArt). Thin steel walls: the wall
  thickness is derived from a drawn body mass of 1.2-2.4 kg (floor 1.5x the wall), because
  4-8 mm steel walls at 7800 kg/m^3 give 2-8 kg buckets, too heavy for a hand to lift.
* The bail radius clears the rim over the whole swing: R = sqrt(r_top^2 + drop^2) + tube + clearance.
"""

from __future__ import annotations

import math

import numpy as np

from dexart_lite.objects import geometry as g
from dexart_lite.objects.model import BODY_RGBA, PART_RGBA, CategorySpec, JointModel, LinkModel, ObjectModel, Param

BODY_DENSITY = 7800.0  # kg/m^3
BAIL_DENSITY = 100.0  # kg/m^3
LUG_GAP = 0.004  # m, between the lug end and the bail tube (PyBullet margins take 2 mm)
FLOOR_FACTOR = 1.5  # floor thickness / wall thickness

TEMPLATES = {
    "A": "straight cylinder with a round (semicircular) bail",
    "B": "tapered frustum (wider at the top) with a round bail",
    "C": "held out: square pail with rounded corners and a U-shaped bail with a straight grip tube",
}

PARAMS = (
    Param("height", "m", "body height", {t: (0.15, 0.26) for t in "ABC"}, heldout=((0.4, 0.6), (0.88, 1.0))),
    Param("radius", "m", "bottom radius (square: half side)", {t: (0.075, 0.115) for t in "ABC"},
          heldout=((0.4, 0.6), (0.0, 0.12))),
    Param("taper", "-", "top / bottom size", {"A": (1.0, 1.0), "B": (1.12, 1.35), "C": (1.0, 1.2)}),
    Param("body_mass", "kg", "target body mass; sets the wall thickness", {t: (1.2, 2.4) for t in "ABC"}),
    Param("pivot_drop", "m", "pivot line below the rim", {t: (0.008, 0.03) for t in "ABC"}),
    Param("bail_clear", "m", "radial clearance between bail and rim", {t: (0.004, 0.012) for t in "ABC"}),
    Param("tube_r", "m", "bail tube radius (DexArt's thick handles)", {t: (0.005, 0.009) for t in "ABC"}),
    Param("grip_rise", "m", "U-bail grip height above the minimum",
          {"A": (0.0, 0.0), "B": (0.0, 0.0), "C": (0.0, 0.04)}),
)


def _outline(template: str, half: float) -> np.ndarray:
    """Counter-clockwise wall outline ``(N, 2)``: 16-gon, or a rounded square for template C."""
    if template == "C":
        return g.rounded_rectangle(half, half, 0.25 * half, per_corner=3)
    return g.superellipse(half, half, 2.0, 16)


def _body_pieces(template: str, p: dict, wall: float) -> list:
    bottom = _outline(template, p["radius"])
    top = bottom * p["taper"]
    return [g.prism(bottom, 0.0, FLOOR_FACTOR * wall)] + g.wall_sectors(bottom, top, 0.0, p["height"], wall)


def wall_thickness(template: str, p: dict) -> float:
    """Wall thickness (m, rounded to 0.05 mm) that gives the body (without lugs) ``body_mass``."""
    wall = 0.002
    for _ in range(3):  # the mass is nearly linear in the thickness; three fixed-point steps suffice
        mass = g.mass_properties(_body_pieces(template, p, wall), BODY_DENSITY).mass
        wall *= p["body_mass"] / mass
    return round(wall, 5)


def build(template: str, p: dict) -> ObjectModel:
    height, drop, tube = p["height"], p["pivot_drop"], p["tube_r"]
    wall = wall_thickness(template, p)
    top_half = p["radius"] * p["taper"]  # outer radius (or half side) at the rim
    z_pivot = height - drop
    half_at_pivot = p["radius"] + (top_half - p["radius"]) * z_pivot / height
    # Every rim point is within sqrt(top_half^2 + drop^2) of the pivot line, at |y| <= top_half.
    rim_reach = math.hypot(top_half, drop)

    if template == "C":  # U-bail: vertical legs at |y| = leg_y, straight grip at grip_z
        leg_y = top_half + tube + p["bail_clear"]
        grip_z = rim_reach + tube + p["bail_clear"] + p["grip_rise"]
        corners = [(0.0, -leg_y, 0.0), (0.0, -leg_y, grip_z), (0.0, leg_y, grip_z), (0.0, leg_y, 0.0)]
        bail = g.polyline_rods(corners, tube, sections=8) + [g.ball(tube, c) for c in corners[1:3]]
        pivot_y, apex = leg_y, np.array([0.0, 0.0, grip_z])
    else:  # semicircular bail through both pivots, in the y-z plane
        # 10 straight rods approximate the arc; their vertices sit 1/cos(pi/20) out so that the chord
        # midpoints keep the designed clearance.
        radius = (rim_reach + tube + p["bail_clear"]) / math.cos(math.pi / 20)
        s = np.linspace(0.0, math.pi, 11)
        bail = g.polyline_rods(np.stack([np.zeros_like(s), radius * np.cos(s), radius * np.sin(s)], 1), tube)
        pivot_y, apex = radius, np.array([0.0, 0.0, radius])

    body = _body_pieces(template, p, wall)
    for sign in (-1.0, 1.0):  # pivot lugs: from inside the wall out to just short of the bail tube
        body.append(g.rod((0.0, sign * (half_at_pivot - wall), z_pivot),
                          (0.0, sign * (pivot_y - tube - LUG_GAP), z_pivot), 0.8 * tube, sections=8))

    joint = JointModel(
        name="bail_hinge", xyz=np.array([0.0, 0.0, z_pivot]), rpy=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0),
        lower=-math.pi / 2, upper=math.pi / 2, init=-math.pi / 2, target=0.0, friction=0.0,
    )
    model = ObjectModel(
        category="bucket", template=template,
        body=LinkModel("body", body, BODY_DENSITY, BODY_RGBA),
        part=LinkModel("bail", bail, BAIL_DENSITY, PART_RGBA),
        joint=joint, grasp_point=apex, fixed_base=False,
        notes={"wall_t": wall, "floor_t": FLOOR_FACTOR * wall, "bail_half_span": pivot_y, "apex_height": apex[2]},
    )
    model.center_footprint()
    return model


SPEC = CategorySpec(
    name="bucket", templates=TEMPLATES, params=PARAMS, primary=("height", "radius"), build=build,
    summary_keys=("height", "radius", "taper", "body_mass"),
)
