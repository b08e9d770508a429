"""Procedural faucets: a fixed body (deck plate, column, spout, valve) and a handle on the valve.

Frames (body frame = object root: origin on the column axis at the centre of the round deck plate,
z = 0 at the bottom of the plate; the robot stands at -x):

* The spout leaves the column toward -x (toward the robot), below the handle.
* Handle frame = joint frame: origin on the valve axis at the hub's mid-height, the hub 3 mm above the
  valve top; rpy = 0, so its axes are the body's. Joint axis (0, 0, 1) (vertical, the valve axis).
* q = 0: "off"; the lever (template A) points toward -x, toward the robot. Limits +-limit with
  limit in [2.5, 3.0] rad: DexArt counts |q| > 1.5 rad as success in either direction, and PyBullet's
  soft limits overshoot by up to 0.24 rad, so the limits sit well outside the threshold.
* init = 0, target = 0 (unused by the task: success is |q| > 1.5).
* Grasp point = the handle link origin (hub centre, on the axis): DexArt's faucet handle point is the
  origin of the ``switch`` link.
* Joint friction is a drawn parameter, 0.05-0.3 N*m.
"""

from __future__ import annotations

import math

import numpy as np

from dexart_lite.objects import geometry as g
from dexart_lite.objects.model import BODY_RGBA, PART_RGBA, CategorySpec, JointModel, LinkModel, ObjectModel, Param

DENSITY = 7800.0  # kg/m^3, DexArt's faucet density
GAP = 0.003  # m, hub above the valve top (PyBullet adds 1 mm of collision margin per shape)

TEMPLATES = {
    "A": "single top lever on a round hub",
    "B": "cross knob: four spokes with ball ends",
    "C": "held out: wing (paddle) handle, two tall flat blades",
}

_ALL = ("A", "B", "C")


def _same(lo: float, hi: float) -> dict[str, tuple[float, float]]:
    return {t: (lo, hi) for t in _ALL}


PARAMS = (
    Param("deck_r", "m", "deck plate radius", _same(0.045, 0.07)),
    Param("deck_t", "m", "deck plate thickness", _same(0.008, 0.015)),
    Param("col_h", "m", "column height above the deck (sets the handle-top height)", _same(0.10, 0.22),
          heldout=((0.4, 0.6), (0.88, 1.0))),
    Param("col_r", "m", "column radius", _same(0.018, 0.032)),
    Param("valve_h", "m", "valve cap height above the column", _same(0.0, 0.03)),
    Param("valve_ratio", "-", "valve radius / column radius", _same(0.75, 1.0)),
    Param("spout_frac", "-", "spout height / column height", _same(0.45, 0.75)),
    Param("spout_reach", "m", "horizontal spout reach from the column axis", _same(0.10, 0.18)),
    Param("spout_r", "m", "spout tube radius", _same(0.008, 0.014)),
    Param("spout_drop_frac", "-", "nozzle length / spout height above the deck", _same(0.2, 0.45)),
    Param("hub_r", "m", "handle hub radius", _same(0.014, 0.024)),
    Param("hub_h", "m", "handle hub height", _same(0.015, 0.03)),
    Param("lever_len", "m", "lever / spoke / wing length from the axis", _same(0.06, 0.12),
          heldout=((0.4, 0.6), (0.0, 0.12))),
    Param("lever_t", "m", "lever / spoke / wing thickness", _same(0.008, 0.015)),
    Param("lever_tilt", "rad", "upward tilt of the lever", {"A": (0.0, 0.3), "B": (0.0, 0.0), "C": (0.0, 0.0)}),
    Param("wing_h", "m", "wing blade height at its tip", {"A": (0.0, 0.0), "B": (0.0, 0.0), "C": (0.03, 0.05)}),
    Param("friction", "N*m", "joint friction (velocity-motor force)", _same(0.05, 0.3)),
    Param("limit", "rad", "symmetric joint limit", _same(2.5, 3.0)),
)


def _handle(template: str, p: dict) -> list:
    """Handle pieces in the handle frame (origin at the hub centre, axis +z)."""
    hub_h, length, t = p["hub_h"], p["lever_len"], p["lever_t"]
    pieces = [g.disk(p["hub_r"], -hub_h / 2, hub_h / 2, sections=12)]
    if template == "A":  # one lever toward -x, tilted up, flattened rectangular section
        tip = np.array([-length * math.cos(p["lever_tilt"]), 0.0, length * math.sin(p["lever_tilt"])])
        section = [(0.0, dy, dz) for dy in (-t / 2, t / 2) for dz in (-0.35 * t, 0.35 * t)]
        pieces.append(g.hull([np.array(s) for s in section] + [tip + s for s in section]))
    elif template == "B":  # four spokes (-x, +y, +x, -y) with ball ends
        for k in range(4):
            direction = np.array([-math.cos(k * math.pi / 2), -math.sin(k * math.pi / 2), 0.0])
            pieces.append(g.rod(0.3 * p["hub_r"] * direction, length * direction, t / 2, sections=8))
            pieces.append(g.ball(0.8 * t, length * direction))
    else:  # two flat wing blades along +-x, rising from the hub height to wing_h at the tips
        for sign in (-1.0, 1.0):
            outline = [(0.0, -hub_h / 2), (0.0, hub_h / 2), (sign * length, -hub_h / 2),
                       (sign * length, -hub_h / 2 + p["wing_h"])]
            pieces.append(g.hull([(x, dy, z) for x, z in outline for dy in (-0.3 * t, 0.3 * t)]))
    return pieces


def build(template: str, p: dict) -> ObjectModel:
    deck_t, col_h = p["deck_t"], p["col_h"]
    col_top = deck_t + col_h
    valve_r = p["valve_ratio"] * p["col_r"]
    body = [g.disk(p["deck_r"], 0.0, deck_t, sections=16), g.disk(p["col_r"], deck_t, col_top, sections=12)]
    valve_top = col_top
    if p["valve_h"] > 0.002:
        valve_top = col_top + p["valve_h"]
        body.append(g.disk(valve_r, col_top, valve_top, sections=12))
    # Spout toward -x: a horizontal arm from inside the column, an elbow ball, a nozzle down.
    z_spout = deck_t + p["spout_frac"] * col_h
    elbow = (-p["spout_reach"], 0.0, z_spout)
    nozzle = (-p["spout_reach"], 0.0, z_spout - p["spout_drop_frac"] * (z_spout - deck_t))
    body += [g.rod((-0.5 * p["col_r"], 0.0, z_spout), elbow, p["spout_r"], sections=10),
             g.ball(p["spout_r"], elbow), g.rod(elbow, nozzle, p["spout_r"], sections=10)]

    hub_center = np.array([0.0, 0.0, valve_top + GAP + p["hub_h"] / 2])
    joint = JointModel(
        name="switch", xyz=hub_center, rpy=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0),
        lower=-p["limit"], upper=p["limit"], init=0.0, target=0.0, friction=p["friction"],
    )
    model = ObjectModel(
        category="faucet", template=template,
        body=LinkModel("body", body, DENSITY, BODY_RGBA),
        part=LinkModel("handle", _handle(template, p), DENSITY, PART_RGBA),
        joint=joint, grasp_point=np.zeros(3), fixed_base=True,
    )
    model.center_footprint()
    model.notes["handle_height"] = float(joint.xyz[2])
    return model


SPEC = CategorySpec(
    name="faucet", templates=TEMPLATES, params=PARAMS, primary=("col_h", "lever_len"), build=build,
    summary_keys=("col_h", "lever_len", "spout_reach", "limit"),
)
