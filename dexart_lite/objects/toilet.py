"""Procedural toilets: a fixed body (pedestal, bowl, seat ring, back deck, tank) and a lid.

Frames (body frame = object root: origin at the centre of the footprint (the pedestal, under the bowl),
z = 0 at the bottom; the bowl opens toward -x, the robot's side):

* The lid hinge is at the back of the bowl (+x), at the mid-thickness of the closed lid, 1 mm + lid_t/2
  above the seat ring. The lid's hinge-side corners stay lid_t / 2 from the axis, above the seat.
* Lid frame = joint frame: origin on the hinge axis, rpy = 0 (axes = body axes); the closed lid
  extends toward -x. Joint axis (0, 1, 0).
* q = 0: closed; q > 0 lifts the front edge up and back. Limits [0, theta_max], theta_max in
  [1.7, 2.0] rad. The tank's front face sits 4 mm behind the lid at theta_max, so past the (soft)
  limit the lid stops against the tank, as on a real toilet.
* The footprint is the pedestal alone, centred under the bowl; the back deck and the tank overhang
  it. So the root (and DexArt's yaw randomisation) turns about the bowl centre, and the lid's front
  edge stays within about 0.22 m of it: under DexArt's toilet randomisation (0.2 m one-sided on x, y
  and z, +-45 deg of yaw) that is what keeps it inside the arm's reach (see ``placement.py``).
* init = 0.25 rad (DexArt ``init_open_rad``); target ("middle") = clip(theta_max - 0.3, 1.4, 1.6).
* Grasp point = the centre of the lid's front edge (mid-thickness), in the lid frame.
* Joint friction = 1.3 x the largest gravity torque of the lid, rounded up to 0.01 N*m.
* The seat ring is part of the body (no separate seat link), so nothing needs locking.
"""

from __future__ import annotations

import math

import numpy as np

from dexart_lite.objects import geometry as g
from dexart_lite.objects.model import (
    BODY_RGBA,
    HOLD_FACTOR,
    PART_RGBA,
    CategorySpec,
    JointModel,
    LinkModel,
    ObjectModel,
    Param,
    ceil_to,
)

DENSITY = 50.0  # kg/m^3, DexArt's toilet density (body and lid)
GAP = 0.001  # m, closed lid above the seat ring
INIT = 0.25  # rad, DexArt init_open_rad
TANK_CLEARANCE = 0.004  # m, lid to tank at theta_max (past it, the tank stops the lid)
BOWL_TAPER = 0.7  # bowl bottom outline / rim outline
OUTLINE_POINTS = 16  # bowl and seat sectors
LID_POINTS = 48  # lid outline resolution

TEMPLATES = {
    "A": "elongated oval bowl and lid, with a tank",
    "B": "round bowl and lid, with a tank",
    "C": "held out: squarish (superellipse) bowl and lid, tankless",
}

PARAMS = (
    Param("rim_h", "m", "seat height (sets the hinge height)", {t: (0.34, 0.42) for t in "ABC"},
          heldout=((0.4, 0.6), (0.0, 0.12))),
    Param("bowl_w", "m", "bowl outer width (sets the lid width)", {t: (0.28, 0.36) for t in "ABC"},
          heldout=((0.4, 0.6), (0.88, 1.0))),
    Param("ratio", "-", "bowl length / width", {"A": (1.1, 1.25), "B": (0.95, 1.05), "C": (0.95, 1.1)}),
    Param("power", "-", "superellipse exponent of the outline", {"A": (2.0, 2.0), "B": (2.0, 2.0), "C": (3.5, 5.0)}),
    Param("bowl_depth", "m", "bowl depth below the seat", {t: (0.10, 0.15) for t in "ABC"}),
    Param("wall_t", "m", "bowl wall thickness", {t: (0.012, 0.02) for t in "ABC"}),
    Param("seat_w", "m", "seat ring width", {t: (0.035, 0.055) for t in "ABC"}),
    Param("seat_t", "m", "seat ring thickness", {t: (0.015, 0.03) for t in "ABC"}),
    Param("lid_t", "m", "lid thickness", {t: (0.015, 0.03) for t in "ABC"}),
    Param("lid_overhang", "m", "lid outline beyond the bowl outline", {t: (0.0, 0.01) for t in "ABC"}),
    Param("hinge_frac", "-", "hinge x / bowl half-length (behind the bowl centre)", {t: (0.82, 0.9) for t in "ABC"}),
    Param("pedestal_frac", "-", "pedestal footprint / bowl outline", {t: (0.55, 0.7) for t in "ABC"}),
    Param("tank_d", "m", "tank depth (0: tankless)", {"A": (0.10, 0.15), "B": (0.10, 0.15), "C": (0.0, 0.0)}),
    Param("tank_h", "m", "tank height above the seat", {"A": (0.18, 0.26), "B": (0.18, 0.26), "C": (0.0, 0.0)}),
    Param("tank_wf", "-", "tank width / bowl width", {"A": (0.85, 1.05), "B": (0.85, 1.05), "C": (0.0, 0.0)}),
    Param("theta_max", "rad", "upper joint limit", {t: (1.7, 2.0) for t in "ABC"}),
)


def target_angle(theta_max: float) -> float:
    """DexArt's "middle" for our toilets: 0.3 rad short of the limit, within [1.4, 1.6]."""
    return round(min(max(theta_max - 0.3, 1.4), 1.6), 4)


def clip_outline(outline: np.ndarray, x_max: float) -> np.ndarray:
    """The part of a convex closed outline ``(N, 2)`` with x <= x_max (edges cut at x = x_max)."""
    out = []
    for a, b in zip(outline, np.roll(outline, -1, axis=0)):
        if a[0] <= x_max:
            out.append(a)
        if (a[0] - x_max) * (b[0] - x_max) < 0:  # the edge crosses the cut
            t = (x_max - a[0]) / (b[0] - a[0])
            out.append(a + t * (b - a))
    return np.array(out)


def tank_offset(lid_length: float, lid_t: float, tank_top: float, theta: float) -> float:
    """How far behind the hinge (m) the lid reaches below height ``tank_top`` at opening ``theta``.

    The lid's top face at distance s from the hinge is at X = -s cos(theta) + (lid_t/2) sin(theta),
    Z = s sin(theta) + (lid_t/2) cos(theta) relative to the hinge; X grows with s, so the furthest
    point below ``tank_top`` is at the largest s with Z <= tank_top.
    """
    s = min(lid_length, (tank_top - 0.5 * lid_t * math.cos(theta)) / math.sin(theta))
    return -s * math.cos(theta) + 0.5 * lid_t * math.sin(theta)


def build(template: str, p: dict) -> ObjectModel:
    b = p["bowl_w"] / 2
    a = p["ratio"] * b  # bowl half-length (x)
    seat_top = p["rim_h"]
    bowl_top = seat_top - p["seat_t"]  # the seat ring sits on the bowl rim
    z_bottom = bowl_top - p["bowl_depth"]
    rim = g.superellipse(a, b, p["power"], OUTLINE_POINTS)  # outer outline at the rim, bowl centre at 0
    bowl_floor = BOWL_TAPER * rim
    body = g.wall_sectors(bowl_floor, rim, z_bottom, bowl_top, p["wall_t"])
    body += g.ring_sectors(rim, p["seat_w"], bowl_top, seat_top)  # the seat ring
    body.append(g.prism(bowl_floor, z_bottom - 0.015, z_bottom))
    pedestal = g.superellipse(p["pedestal_frac"] * a, p["pedestal_frac"] * b, p["power"], OUTLINE_POINTS)
    body.append(g.hull(np.vstack([np.column_stack([pedestal, np.zeros(len(pedestal))]),
                                  np.column_stack([bowl_floor, np.full(len(bowl_floor), z_bottom - 0.015)])])))

    hinge_x = p["hinge_frac"] * a
    hinge = np.array([hinge_x, 0.0, seat_top + GAP + p["lid_t"] / 2])
    lid_outline = clip_outline(g.superellipse(a + p["lid_overhang"], b + p["lid_overhang"], p["power"], LID_POINTS),
                               hinge_x) - [hinge_x, 0.0]
    lid_length = -lid_outline[:, 0].min()  # hinge to front edge
    lid = g.prism(lid_outline, -p["lid_t"] / 2, p["lid_t"] / 2)

    # Back deck (carries the hinge and the tank) from the rear of the seat backward; it stays above the
    # floor, so the footprint is the pedestal's.
    deck_front = a - 0.5 * p["seat_w"]
    deck_half_w = 0.45 * b
    if p["tank_d"] > 0:
        tank_top = p["rim_h"] + p["tank_h"]
        reach = tank_offset(lid_length, p["lid_t"], tank_top - hinge[2], p["theta_max"])
        tank_front = hinge_x + max(reach, 0.5 * p["lid_t"]) + TANK_CLEARANCE
        tank_back = tank_front + p["tank_d"]
        tank_outline = g.rounded_rectangle(p["tank_d"] / 2, p["tank_wf"] * b, 0.02) + [tank_front + p["tank_d"] / 2, 0]
        body.append(g.prism(tank_outline, bowl_top - 0.06, tank_top))
        deck_back = tank_back
    else:
        deck_back = hinge_x + 0.05
    deck_bottom = 0.45 * bowl_top
    body.append(g.box((deck_back - deck_front, 2 * deck_half_w, bowl_top - deck_bottom),
                      ((deck_front + deck_back) / 2, 0.0, (bowl_top + deck_bottom) / 2)))

    joint = JointModel(
        name="lid_hinge", xyz=hinge, rpy=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0),
        lower=0.0, upper=p["theta_max"], init=INIT, target=target_angle(p["theta_max"]), friction=0.0,
    )
    model = ObjectModel(
        category="toilet", template=template,
        body=LinkModel("body", body, DENSITY, BODY_RGBA),
        part=LinkModel("lid", [lid], DENSITY, PART_RGBA),
        joint=joint, grasp_point=np.array([-lid_length, 0.0, 0.0]), fixed_base=True,
        notes={"lid_length": lid_length, "length": deck_back + a},
    )
    model.center_footprint()
    joint.friction = ceil_to(HOLD_FACTOR * model.max_gravity_torque(), 0.01)
    model.notes["hinge_height"] = float(joint.xyz[2])
    return model


WIDE_POWER = (2.0, 3.0)  # outline exponent of the wide split's toilets (A / B: 2, the held-out C: 3.5-5)
WIDE_TANKLESS = 0.5  # probability that a wide-split toilet has no tank (every seen toilet has one)


def widen(params: dict, rng: np.random.Generator) -> dict:
    """A wide-split toilet: an A / B draw whose outline may be squarer (exponent up to 3, still below the
    held-out template's 3.5) and which, with probability 0.5, has no tank. The 17 seen toilets are all oval
    or round with a tank, and policies trained on them find the lid by the tank
    (``docs/results/students.md``); these are extra training shapes, never evaluation objects."""
    params = dict(params, power=round(float(rng.uniform(*WIDE_POWER)), 4) + 0.0)
    if rng.uniform() < WIDE_TANKLESS:
        params.update(tank_d=0.0, tank_h=0.0, tank_wf=0.0)
    return params


SPEC = CategorySpec(
    name="toilet", templates=TEMPLATES, params=PARAMS, primary=("rim_h", "bowl_w"), build=build,
    summary_keys=("bowl_w", "ratio", "rim_h", "theta_max", "power", "tank_d"), wide=17, widen=widen,
)
