"""Writes ``urdf/objects/README.md`` from the committed files (run by ``dexart-lite objects generate``).

Every number in the README is read from ``params.json`` / ``checks.json`` or computed from the OBJ
files here, so the README cannot drift from the objects it describes.
"""

from __future__ import annotations

import json
from pathlib import Path
from string import Template

import numpy as np

from dexart_lite.objects import CATEGORIES, HALF_SIZES, ROBOT_BASE, all_objects, geometry
from dexart_lite.objects import report as split_report
from dexart_lite.objects.feasibility import BUCKET_LIFT, DRIVE_TORQUE, LIFT_FORCE
from dexart_lite.objects.generate import (CATEGORY_SPECS, CHECKS_FILE, DUPLICATE_EPS, GENERATED_SPLITS, GENERATOR_VERSION,
                                         SPLIT_SIZES, WIDE_SIZES)
from dexart_lite.objects.placement import MIN_FRONT, RAND_POS, RAND_YAW_DEG, REACH, SHOULDER_HEIGHT, grasp_x_stats

CONVENTIONS = {  # category -> (part link, joint, axis and sign, q = 0, limits, init, target, grasp point)
    "faucet": ("handle", "switch", "(0, 0, 1) vertical valve axis; q > 0 turns counter-clockwise seen from above",
               "off; the lever (template A) points toward the robot (-x)", "+-limit, limit in [2.5, 3.0]", "0",
               "0 (success is abs(q) > 1.5)", "handle link origin: the hub centre on the valve axis"),
    "bucket": ("bail", "bail_hinge", "(0, 1, 0) = the pivot line; q > 0 tips the apex toward +x",
               "bail upright", "[-pi/2, pi/2]", "-pi/2: bail lying toward the robot (-x)", "0 (upright)",
               "bail apex at q = 0 (grip-tube centre line)"),
    "laptop": ("lid", "lid_hinge", "(0, 1, 0), hinge at the far (+x) edge; q > 0 lifts the near edge",
               "closed", "[0, theta_max], theta_max in [1.9, 2.4]", "0.2",
               "clip(theta_max - 0.5, 1.4, 1.8)", "lid's highest vertex at the target pose, y = lid mean"),
    "toilet": ("lid", "lid_hinge", "(0, 1, 0), hinge at the back (+x); q > 0 lifts the front edge",
               "closed", "[0, theta_max], theta_max in [1.7, 2.0]", "0.25", "clip(theta_max - 0.3, 1.4, 1.6)",
               "centre of the lid's front edge (mid-thickness)"),
}


def _records(root: Path) -> list[dict]:
    out = []
    for category in CATEGORIES:
        for split in GENERATED_SPLITS:
            recs = [json.loads(p.read_text()) for p in sorted((root / category / split).glob("*/params.json"))]
            out += sorted(recs, key=lambda r: r["index"])
    return out


def _grasp_from_shoulder(r: dict, q: float) -> float:
    """Distance (m) from the shoulder to the grasp point at joint angle ``q``, nominal placement."""
    j = r["joint"]
    rotation = geometry.rpy_matrix(j["origin_rpy"]) @ geometry.axis_rotation(j["axis"], q)
    point = np.add(r["placement"]["position"], np.add(j["origin_xyz"], rotation @ np.asarray(r["grasp_point"])))
    return float(np.linalg.norm(point - [0.0, 0.0, SHOULDER_HEIGHT]))


def _range(values, digits: int = 3) -> str:
    return f"{min(values):.{digits}f}-{max(values):.{digits}f}"


def _param_table(category: str) -> list[str]:
    spec = CATEGORY_SPECS[category]
    lines = ["| parameter | unit | A | B | C (held out) | held-out bands (fraction of range) | meaning |",
             "|---|---|---|---|---|---|---|"]
    for p in spec.params:
        cells = []
        for t in "ABC":
            lo, hi = p.ranges[t]
            cells.append(f"{lo:g}" if lo == hi else f"{lo:g}-{hi:g}")
        bands = ", ".join(f"{lo:g}-{hi:g}" for lo, hi in p.heldout) or "-"
        lines.append(f"| `{p.name}` | {p.unit} | {' | '.join(cells)} | {bands} | {p.doc} |")
    return lines


TEMPLATE = Path(__file__).with_name("README.template.md")  # the prose; ``$name`` marks what is computed here


def _rows(by_cat: dict) -> dict[str, str]:
    """The placement, splits, checks and masses tables' rows (one line per category), from the records."""
    reach, splits, masses = [], [], []
    for c in CATEGORIES:
        recs = by_cat[c]
        stats = [grasp_x_stats(np.subtract(r["placement"]["grasp_nominal"], r["placement"]["position"]), c,
                               r["placement"]["position"], r["placement"]["yaw"]) for r in recs]
        reach.append(f"| {c} | {_range([r['placement']['position'][0] for r in recs])} "
                     f"| {_range([r['placement']['grasp_nominal'][0] for r in recs])} | {_range([s[1] for s in stats])} "
                     f"| {min(s[0] for s in stats):.3f}-{max(s[2] for s in stats):.3f} "
                     f"| {_range([r['placement']['reach_margin'] for r in recs])} |")
        counts = {s: sum(r["split"] == s for r in recs) for s in ("seen", "unseen")}
        if counts != SPLIT_SIZES[c]:
            raise RuntimeError(f"{c} has {counts}, expected {SPLIT_SIZES[c]}; run `objects generate`")
        n_c = sum(r["split"] == "unseen" and r["template"] == "C" for r in recs)
        n_b = sum(r["split"] == "unseen" and r["band"] is not None for r in recs)
        n_wide = sum(r["split"] == "wide" for r in recs)
        if n_wide != WIDE_SIZES[c]:
            raise RuntimeError(f"{c} has {n_wide} wide objects, expected {WIDE_SIZES[c]}; run `objects generate`")
        splits.append(f"| {c} | {counts['seen']} | {counts['unseen']} | {HALF_SIZES[c]} | {n_c} | {n_b} | {n_wide} |")
        dens = f"{recs[0]['links'][recs[0]['body_link']]['density']:g} / {recs[0]['links'][recs[0]['part_link']]['density']:g}"
        tris = [sum(link["triangles"] for link in r["links"].values()) for r in recs]
        masses.append(f"| {c} | {dens} | {_range([r['links'][r['body_link']]['mass'] for r in recs])} "
                      f"| {_range([r['links'][r['part_link']]['mass'] for r in recs])} "
                      f"| {_range([r['joint']['friction'] for r in recs], 2)} | {min(tris)}-{max(tris)} |")
    return {"reach_table": "\n".join(reach), "splits_table": "\n".join(splits), "masses_table": "\n".join(masses)}


def _wide_summary(recs: list[dict]) -> str:
    """How the toilets' wide split came out: its count, tankless count and outline exponents."""
    wide = [r for r in recs if r["split"] == "wide"]
    tankless = sum(r["params"]["tank_d"] == 0 for r in wide)
    return (f"{len(wide)} toilets (templates A / B alternating), {tankless} of them tankless, outline exponent "
            f"{_range([r['params']['power'] for r in wide], 2)}")


def _checks_table(by_cat: dict, checks: dict) -> str:
    lines = []
    for c in CATEGORIES:
        ch = [checks[r["name"]]["checks"] for r in by_cat[c]]
        rejected = sum(sum(checks[r["name"]]["rejected_before"].values()) for r in by_cat[c])
        hold = _range([x["hold_drift"] for x in ch], 4) if c in ("laptop", "toilet") else "-"
        lift = _range([x["lift"] for x in ch]) if c == "bucket" else "-"
        bail = _range([x["lift_bail_q"] for x in ch], 2) if c == "bucket" else "-"
        lines.append(f"| {c} | {_range([1000 * x['min_clearance'] for x in ch], 1)} | {_range([x['reached'] for x in ch], 2)} "
                     f"| {_range([x['passive_drift'] for x in ch], 4)} | {hold} | {lift} | {bail} | {rejected} |")
    return "\n".join(lines)


def _templates_sections() -> str:
    lines = []
    for c in CATEGORIES:
        spec = CATEGORY_SPECS[c]
        lines += [f"### {c}", ""]
        lines += [f"* {t}: {d}" for t, d in spec.templates.items()]
        lines += ["", f"Primary parameters (held-out bands): {', '.join(f'`{p}`' for p in spec.primary)}.", ""]
        lines += _param_table(c) + [""]
    return "\n".join(lines)


def _object_tables(by_cat: dict) -> str:
    lines = []
    for c in CATEGORIES:
        keys = CATEGORY_SPECS[c].summary_keys
        lines += [f"### {c}", "",
                  "| split | # | template | name | " + " | ".join(keys)
                  + " | body / part mass (kg) | friction (N*m) | target (rad) | position (m) |",
                  "|---|---|---|---|" + "---|" * len(keys) + "---|---|---|---|"]
        for r in by_cat[c]:
            dims = " | ".join(f"{r['params'][k]:g}" for k in keys)
            masses = f"{r['links'][r['body_link']]['mass']:.3f} / {r['links'][r['part_link']]['mass']:.3f}"
            pos = ", ".join(f"{v:.3f}" for v in r["placement"]["position"])
            half = " (half)" if r["split"] == "seen" and r["index"] < HALF_SIZES[c] else ""
            lines.append(f"| {r['split']}{half} | {r['index']} | {r['template']} | `{r['name']}` | {dims} | {masses} "
                         f"| {r['joint']['friction']:.2f} | {r['joint']['target']:.3f} | ({pos}) |")
        lines.append("")
    return "\n".join(lines)


def readme_text(root: Path) -> str:
    """``README.template.md`` with every number filled in from the objects under ``root``."""
    root = Path(root)
    records = _records(root)
    checks = json.loads((root / CHECKS_FILE).read_text())
    by_cat = {c: [r for r in records if r["category"] == c] for c in CATEGORIES}
    infos = all_objects(root)
    values = {
        "generator_version": GENERATOR_VERSION, "duplicate_eps": DUPLICATE_EPS, "lift_force": f"{LIFT_FORCE:g}",
        "half_sizes": ", ".join(f"{c} {n}" for c, n in HALF_SIZES.items()), "bucket_lift": BUCKET_LIFT,
        "reach": REACH, "shoulder_height": SHOULDER_HEIGHT, "min_front": MIN_FRONT,
        "drive_torque": ", ".join(f"{v:g} ({c})" for c, v in DRIVE_TORQUE.items()),
        "conventions_table": "\n".join(
            f"| {c} | {'free' if c == 'bucket' else 'fixed'} | `{part}` | `{joint}` | {axis} | {zero} | {limits} "
            f"| {init} | {target} | {grasp} |"
            for c, (part, joint, axis, zero, limits, init, target, grasp) in CONVENTIONS.items()),
        "placement_table": "\n".join(
            f"| {c} | ({', '.join(f'{v:g}' for v in ROBOT_BASE[c])}) | {RAND_POS[c]:g} | {RAND_YAW_DEG[c]:g} |"
            for c in CATEGORIES),
        "toilet_distance": _range([float(np.hypot(*np.subtract(r["placement"]["grasp_nominal"],
                                                                r["placement"]["position"])[:2]))
                                   for r in by_cat["toilet"]]),
        "lid_reach": " and ".join(f"{c} {_range([_grasp_from_shoulder(r, r['joint']['target']) for r in by_cat[c]])} m"
                                  for c in ("laptop", "toilet")),
        "templates": _templates_sections(), "checks_table": _checks_table(by_cat, checks),
        "split_report": "\n\n".join(split_report.category_report(
            c, [i for i in infos if i.category == c and i.split == "seen"],
            [i for i in infos if i.category == c and i.split == "unseen"]).text() for c in CATEGORIES),
        "wide_toilets": _wide_summary(by_cat["toilet"]),
        "montages": "\n".join(f"* [{c}](montage_{c}.png)" for c in CATEGORIES),
        "objects_tables": _object_tables(by_cat), **_rows(by_cat)}
    return Template(TEMPLATE.read_text()).substitute(values)
