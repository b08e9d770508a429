"""Procedural laptops: a keyboard base (fixed) and a lid (the functional part) on a hinge.

Frames (body frame = object root: origin at the centre of the base's footprint, z = 0 at its bottom;
the robot stands at -x):

* The hinge is at the far (+x) edge of the base, at the mid-thickness of the closed lid. Because the
  axis runs through the lid's mid-thickness, the lid's hinge-side corners stay at lid_t / 2 from the
  axis and never dip into the base at any opening.
* Lid frame = joint frame: origin on the hinge axis, the closed lid extends toward -x.
  Joint axis (0, 1, 0) in the lid frame; for templates A and B the joint origin has rpy = 0, so the
  axis is +y of the body. Template C (wedge base) tilts the joint frame by rpy = (0, -slope, 0) so that
  the closed lid lies on the sloped top; the axis stays +y.
* q = 0: closed (the lid rests 1 mm above the base, on its lower limit). q > 0 lifts the near (-x) edge
  up and away from the robot. Limits [0, theta_max].
* init = 0.2 rad (DexArt ``init_open_rad``); target ("middle") = clip(theta_max - 0.5, 1.4, 1.8) rad.
* Grasp point = the lid's highest vertex at the target pose (x and z of that vertex, y = mean of the
  lid vertices), expressed in the lid frame, as DexArt computes the laptop "handle" point.
* Joint friction = 1.3 x the largest gravity torque of the lid over the range, rounded up to 0.01 N*m:
  the lid holds any opening when released and opens with a small push.
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

DENSITY = 500.0  # kg/m^3, DexArt's laptop density (body and lid)
GAP = 0.001  # m, closed lid above the base top
INIT = 0.2  # rad, DexArt init_open_rad

TEMPLATES = {
    "A": "sharp slab: box base and box lid",
    "B": "rounded slab: rounded-rectangle base and lid",
    "C": "held out: wedge base (thicker at the back) and a lid with a hinge barrel behind the base",
}

PARAMS = (
    Param("width", "m", "base and lid width (y)", {"A": (0.26, 0.36), "B": (0.26, 0.36), "C": (0.26, 0.36)}),
    Param("depth_ratio", "-", "base depth / width", {"A": (0.62, 0.80), "B": (0.62, 0.80), "C": (0.62, 0.80)},
          heldout=((0.4, 0.6), (0.88, 1.0))),
    Param("base_t", "m", "base thickness (front thickness for the wedge)",
          {"A": (0.012, 0.022), "B": (0.012, 0.022), "C": (0.010, 0.016)}),
    Param("lid_t", "m", "lid thickness", {"A": (0.005, 0.011), "B": (0.005, 0.011), "C": (0.005, 0.011)},
          heldout=((0.4, 0.6), (0.0, 0.12))),
    Param("lid_ratio", "-", "lid depth / base depth", {"A": (0.92, 1.0), "B": (0.92, 1.0), "C": (0.92, 1.0)}),
    Param("hinge_inset", "m", "hinge axis in front of the base's back edge",
          {"A": (0.0, 0.008), "B": (0.0, 0.008), "C": (0.0, 0.0)}),
    Param("theta_max", "rad", "upper joint limit", {"A": (1.9, 2.4), "B": (1.9, 2.4), "C": (1.9, 2.4)}),
    Param("corner_r", "m", "corner radius of base and lid outlines",
          {"A": (0.0, 0.0), "B": (0.008, 0.02), "C": (0.004, 0.008)}),
    Param("wedge", "m", "extra base thickness at the back", {"A": (0.0, 0.0), "B": (0.0, 0.0), "C": (0.006, 0.014)}),
    Param("barrel_r", "m", "hinge barrel radius", {"A": (0.0, 0.0), "B": (0.0, 0.0), "C": (0.006, 0.010)}),
)


def target_angle(theta_max: float) -> float:
    """DexArt's "middle" for our laptops: comfortably open, 0.5 rad short of the limit."""
    return round(min(max(theta_max - 0.5, 1.4), 1.8), 4)


def build(template: str, p: dict) -> ObjectModel:
    width, depth = p["width"], p["width"] * p["depth_ratio"]
    outline = g.rounded_rectangle(depth / 2, width / 2, p["corner_r"])  # (N, 2), centred on the base

    def top(x: float) -> float:
        """Height of the base's (possibly sloped) top surface at body x."""
        return p["base_t"] + p["wedge"] * (x + depth / 2) / depth

    base_pts = [(x, y, 0.0) for x, y in outline] + [(x, y, top(x)) for x, y in outline]
    base = g.hull(base_pts)

    slope = math.atan2(p["wedge"], depth)  # rad, top-surface slope (0 for flat bases)
    if p["barrel_r"] > 0:  # barrel hinge just behind the base's back edge
        hinge_x = depth / 2 + p["barrel_r"] + 0.001
    else:
        hinge_x = depth / 2 - p["hinge_inset"]
    normal = np.array([-math.sin(slope), 0.0, math.cos(slope)])  # unit normal of the top surface
    hinge = np.array([hinge_x, 0.0, top(hinge_x)]) + (GAP + p["lid_t"] / 2) * normal

    # Lid in its own frame: hinge axis at the origin, the closed lid extends to -x.
    lid_depth = p["lid_ratio"] * depth
    lid_outline = g.rounded_rectangle(lid_depth / 2, width / 2, p["corner_r"]) - [lid_depth / 2, 0.0]
    lid_pieces = [g.prism(lid_outline, -p["lid_t"] / 2, p["lid_t"] / 2)]
    if p["barrel_r"] > 0:
        half = 0.4 * width
        lid_pieces.append(g.rod((0.0, -half, 0.0), (0.0, half, 0.0), p["barrel_r"], sections=12))

    joint = JointModel(
        name="lid_hinge", xyz=hinge, rpy=(0.0, -slope, 0.0), axis=(0.0, 1.0, 0.0),
        lower=0.0, upper=p["theta_max"], init=INIT, target=target_angle(p["theta_max"]), friction=0.0,
    )
    model = ObjectModel(
        category="laptop", template=template,
        body=LinkModel("base", [base], DENSITY, BODY_RGBA),
        part=LinkModel("lid", lid_pieces, DENSITY, PART_RGBA),
        joint=joint, grasp_point=np.zeros(3), fixed_base=True,
        notes={"depth": depth, "lid_depth": lid_depth},
    )
    model.center_footprint()
    joint.friction = ceil_to(HOLD_FACTOR * model.max_gravity_torque(), 0.01)

    # Grasp point: the lid's highest vertex at the target pose (DexArt's laptop handle point).
    verts = np.vstack([piece.vertices for piece in lid_pieces])  # lid frame
    posed = verts @ joint.part_to_body(joint.target)[:3, :3].T
    top_vertex = verts[int(np.argmax(posed[:, 2]))]
    model.grasp_point = np.array([top_vertex[0], verts[:, 1].mean(), top_vertex[2]])
    model.notes["hinge_height"] = float(joint.xyz[2])
    return model


SPEC = CategorySpec(
    name="laptop", templates=TEMPLATES, params=PARAMS, primary=("depth_ratio", "lid_t"), build=build,
    summary_keys=("width", "depth_ratio", "lid_t", "theta_max"),
)
