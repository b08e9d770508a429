"""Writes ``urdf/objects/README.md`` from the committed files (run by ``dexart-lite objects generate``).

Every number in the README is read from ``params.json`` / ``checks.json`` or computed from the OBJ
files here, so the README cannot drift from the objects it describes.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dexart_lite.objects import CATEGORIES, HALF_SIZES, ROBOT_BASE, all_objects, geometry
from dexart_lite.objects import report as split_report
from dexart_lite.objects.feasibility import BUCKET_LIFT, DRIVE_TORQUE, LIFT_FORCE
from dexart_lite.objects.generate import CHECKS_FILE, DUPLICATE_EPS, GENERATOR_VERSION, SPECS, SPLIT_SIZES
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
        for split in ("seen", "unseen"):
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
    spec = SPECS[category]
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


def readme_text(root: Path) -> str:
    root = Path(root)
    records = _records(root)
    checks = json.loads((root / CHECKS_FILE).read_text())
    by_cat = {c: [r for r in records if r["category"] == c] for c in CATEGORIES}
    infos = all_objects(root)
    lines = [
        "# Articulated objects",
        "",
        "Procedurally generated stand-ins for DexArt's PartNet-Mobility objects (which cannot be shipped).",
        "**Generated files: do not edit.** Regenerate with `dexart-lite objects generate` (this README",
        "included); the generators live in `dexart_lite/objects/`. Load them through the catalog:",
        "`dexart_lite.objects.list_objects(category, split)` / `get_object(name)`.",
        "",
        "## Layout and naming",
        "",
        "```",
        "urdf/objects/<category>/<split>/<name>/",
        "    <name>.urdf      two links + one revolute joint; meshes referenced relative to this folder",
        "    <body>.obj       root link, one `o` block per convex piece (PyBullet builds a compound of hulls)",
        "    <part>.obj       functional part, same format; used as both visual and collision mesh",
        "    params.json      generator parameters, seed, joint, placement, grasp point, link masses",
        "urdf/objects/checks.json   physics-check measurements of every object",
        "```",
        "",
        "* `<name>` = `<category>_` + the first 10 hex digits of the SHA-1 of the canonical parameters",
        f"  (category, template, parameters, generator version {GENERATOR_VERSION}). PyBullet caches URDFs and",
        "  meshes by path, so a folder is never rewritten with other content: new parameters, new name.",
        "* Seeds are fixed per (category, split, index, attempt) (SHA-256 of a string, not Python's `hash`);",
        "  regenerating reproduces every file byte for byte (`tests/test_objects.py` checks a sample).",
        "* `seen_half` is not a folder: it is the first N seen objects by index "
        f"({', '.join(f'{c} {n}' for c, n in HALF_SIZES.items())}).",
        "",
        "## Loading them",
        "",
        "* `loadURDF(path, flags=URDF_USE_INERTIA_FROM_FILE, useFixedBase=not bucket)`: without the flag PyBullet",
        "  recomputes the inertia from the collision shapes' bounding boxes and ignores the inertia written here.",
        "* Joint friction: `setJointMotorControl2(body, 0, VELOCITY_CONTROL, targetVelocity=0, force=joint_friction)`",
        "  (a velocity motor with capped force; never URDF damping, which is explicit and unstable for light parts).",
        "  This also replaces PyBullet's default joint motor.",
        "* `getBasePositionAndOrientation` returns the root's centre of mass, not the root frame: convert with",
        "  the inertial frame from `getDynamicsInfo(body, -1)[3:5]` when the root frame is needed (bucket height).",
        "* The functional part is link index 0 and its joint is joint index 0; the body is the root (-1). For",
        "  segmentation, `ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX` gives `uid + ((link + 1) << 24)`.",
        "",
        "## Conventions",
        "",
        "Root frame: origin at the centre of the object's footprint (the x-y bounding box of the body's",
        "lowest vertices), z = 0 at its bottom. The robot stands at -x facing +x, so the functional part faces",
        "-x; the cameras look from +y. Every link has an `<inertial>` computed from its convex pieces (pieces",
        "summed as disjoint) at DexArt's densities. Functional parts are red, bodies light grey.",
        "",
        "| category | base | part link | joint | axis (in the joint frame; joint origin rpy = 0 except the C laptop's wedge tilt) | q = 0 | limits (rad) | init (rad) | target (rad) | grasp point (part frame) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in CATEGORIES:
        part, joint, axis, zero, limits, init, target, grasp = CONVENTIONS[c]
        base = "free" if c == "bucket" else "fixed"
        lines.append(f"| {c} | {base} | `{part}` | `{joint}` | {axis} | {zero} | {limits} | {init} | {target} | {grasp} |")
    lines += [
        "",
        "Category details (written in each generator's docstring):",
        "",
        "* **faucet**: deck plate, column, spout toward -x, optional valve cap; the handle hub sits 3 mm above",
        "  the valve (no resting contact, so the joint only feels the friction motor). Friction is drawn in",
        "  0.05-0.3 N*m. Density 7800.",
        "* **bucket**: free body on the table; the bail turns about the line through its two pivots (the lugs",
        "  on the +-y sides of the wall). The bail radius clears the rim over the whole swing. Friction 0.",
        "  Densities: body 7800, bail 100. **Deviation:** with 4-8 mm walls (assets.md's range) a 7800 kg/m^3",
        "  bucket of this size weighs 2-8 kg; here the wall thickness is derived from a drawn body mass of",
        "  1.2-2.4 kg instead, which gives steel-like walls of about 1-2 mm (`derived.wall_t` in params.json).",
        "* **laptop**: hinge axis at the far edge of the base, at the closed lid's mid-thickness, so the lid",
        "  never dips into the base at any opening; the closed lid rests 1 mm above the base on its lower limit.",
        "  Density 500.",
        "* **toilet**: pedestal, bowl (wall sectors), seat ring, back deck and tank are one rigid body; the lid",
        "  hinges at the back of the seat. The tank face sits 4 mm behind the lid at theta_max, so past the soft",
        "  limit the lid stops against the tank. The footprint is the pedestal only, centred under the bowl",
        "  (deck and tank overhang it), so DexArt's yaw randomisation turns the toilet about the bowl centre.",
        "  Density 50.",
        "* Laptop and toilet joint friction = 1.3 x the lid's largest gravity torque over its range (rounded up",
        "  to 0.01 N*m): the lid holds any opening when released, and a small push opens it.",
        "",
        "## Placement and reach",
        "",
        "`position` (params.json `placement`, `ObjectInfo.position`) is the nominal root position relative to",
        "the robot base (world axes), `yaw` the nominal yaw (0 for all). The task adds DexArt's randomisation",
        "on top: U[0, r)^3 on x, y and z, and yaw U[-d, d] about the object's own origin:",
        "",
        "| category | robot base (world, m) | r (m) | d (deg) |",
        "|---|---|---|---|",
        *[f"| {c} | ({', '.join(f'{v:g}' for v in ROBOT_BASE[c])}) | {RAND_POS[c]:g} | {RAND_YAW_DEG[c]:g} |"
          for c in CATEGORIES],
        "",
        "* z = -robot_base_z: the object stands on the table (top at world z = 0).",
        "* y = -r / 2, so the one-sided y noise is centred on the robot's axis.",
        "* x maximises the worst-case reach margin of the grasp point at the reset angle, over the corners of",
        "  the position box and 13 yaws across the yaw range (1 mm grid). Margin = min(",
        f"  {REACH} m - distance from the shoulder (robot base + (0, 0, {SHOULDER_HEIGHT})), x - {MIN_FRONT} m). Objects with a",
        "  negative margin are rejected.",
        "",
        "Ranges over the objects of each category (grasp point at the reset angle, x in front of the robot base):",
        "",
        "| category | nominal root x (m) | grasp x, nominal pose (m) | grasp x, mean under randomisation (m) | grasp x, extremes of randomisation (m) | worst-case reach margin (m) |",
        "|---|---|---|---|---|---|",
    ]
    for c in CATEGORIES:
        recs = by_cat[c]
        xs = [r["placement"]["position"][0] for r in recs]
        gx = [r["placement"]["grasp_nominal"][0] for r in recs]
        stats = [grasp_x_stats(np.subtract(r["placement"]["grasp_nominal"], r["placement"]["position"]), c,
                               r["placement"]["position"], r["placement"]["yaw"]) for r in recs]
        margins = [r["placement"]["reach_margin"] for r in recs]
        lines.append(f"| {c} | {_range(xs)} | {_range(gx)} | {_range([s[1] for s in stats])} "
                     f"| {min(s[0] for s in stats):.3f}-{max(s[2] for s in stats):.3f} | {_range(margins)} |")
    lines += [
        "",
        "Nominal grasp points can sit nearer than 0.35 m because the one-sided noise pushes them away from the",
        "robot (see the mean column); a larger nominal x would push the far corners of the randomisation box out",
        "of reach. The toilet has the smallest margins: with 0.2 m of noise and +-45 deg of yaw about the root,",
        "the horizontal distance from the root to the lid front (here "
        + _range([float(np.hypot(*np.subtract(r["placement"]["grasp_nominal"], r["placement"]["position"])[:2]))
                  for r in by_cat["toilet"]]) + " m) is what limits it.",
        "",
        "The check uses the reset angle, where the hand must first get to. Opened to the target, the laptop's",
        "and toilet's grasp points rise above their hinges, "
        + " and ".join(f"{c} {_range([_grasp_from_shoulder(r, r['joint']['target']) for r in by_cat[c]])} m"
                       for c in ("laptop", "toilet"))
        + f" from the shoulder at the nominal pose (reach {REACH} m): the hand can push the lid lower down instead.",
        "",
        "## Templates and parameters",
        "",
        "Seen objects use templates A and B (alternating by index) with every primary parameter outside its",
        "held-out bands. Unseen objects: the first half (rounded up) use the held-out template C; the others use",
        "A / B with one primary parameter drawn inside a held-out band (interior 40-60 % of the range: interpolation;",
        "outer 12 %: extrapolation), cycling over both primary parameters and both band kinds.",
        f"Near-duplicates (normalised parameter distance < {DUPLICATE_EPS} to an accepted object of the same",
        "template) are rejected.",
        "",
    ]
    for c in CATEGORIES:
        spec = SPECS[c]
        lines += [f"### {c}", ""]
        lines += [f"* {t}: {d}" for t, d in spec.templates.items()]
        lines += ["", f"Primary parameters (held-out bands): {', '.join(f'`{p}`' for p in spec.primary)}.", ""]
        lines += _param_table(c) + [""]

    lines += [
        "## Splits",
        "",
        "| category | seen | unseen | seen_half | unseen from template C | unseen from held-out bands |",
        "|---|---|---|---|---|---|",
    ]
    for c in CATEGORIES:
        recs = by_cat[c]
        n_c = sum(r["split"] == "unseen" and r["template"] == "C" for r in recs)
        n_b = sum(r["split"] == "unseen" and r["band"] is not None for r in recs)
        counts = {s: sum(r["split"] == s for r in recs) for s in ("seen", "unseen")}
        if counts != SPLIT_SIZES[c]:
            raise RuntimeError(f"{root}: {c} has {counts}, expected {SPLIT_SIZES[c]}; run `objects generate`")
        lines.append(f"| {c} | {counts['seen']} | {counts['unseen']} | {HALF_SIZES[c]} | {n_c} | {n_b} |")

    lines += [
        "",
        "## Physics checks",
        "",
        "Every object passed these checks when generated (PyBullet DIRECT, dt = 1/240 s; `feasibility.py`;",
        "numbers per object in `checks.json`). A draw that fails any check is rejected and the next attempt drawn.",
        "",
        "1. No interpenetration between body and part at 25 angles over the range plus the reset angle",
        "   (geometric distance > -0.5 mm; PyBullet's 1 mm collision margins added back).",
        "2. Driven by a position motor capped at joint friction + "
        + ", ".join(f"{v:g} ({c})" for c, v in DRIVE_TORQUE.items()) + " N*m, the joint reaches the",
        "   success threshold in 2 s: faucet abs(q) > 1.5 in both directions; laptop / toilet q >= target; bucket",
        "   bail within 0.3 * pi/2 of upright. Bucket also: a `JOINT_POINT2POINT` constraint at the bail apex",
        f"   (max {LIFT_FORCE:g} N) swings the bail upright (1 s), pulls 0.5 m up (2 s) and holds (1 s): the body must",
        f"   rise > {BUCKET_LIFT} m with the bail within 0.3 * pi/2 of upright (DexArt's success).",
        "3. Released at the reset angle with the friction motor on, nothing moves for 2 s (joint < 0.01 rad,",
        "   root < 2 mm; the bucket stands on a ground plane). Laptop and toilet lids also hold within 0.01 rad",
        "   for 1 s when released at 6 openings across their range.",
        "4. The reach check above.",
        "",
        "| category | min clearance (mm) | reached (rad) | passive drift (rad) | lid hold drift (rad) | bucket lift (m) | bail angle after lift (rad) | draws rejected |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in CATEGORIES:
        ch = [checks[r["name"]]["checks"] for r in by_cat[c]]
        rejected = sum(sum(checks[r["name"]]["rejected_before"].values()) for r in by_cat[c])
        hold = _range([x["hold_drift"] for x in ch], 4) if c in ("laptop", "toilet") else "-"
        lift = _range([x["lift"] for x in ch]) if c == "bucket" else "-"
        bail = _range([x["lift_bail_q"] for x in ch], 2) if c == "bucket" else "-"
        lines.append(f"| {c} | {_range([1000 * x['min_clearance'] for x in ch], 1)} | {_range([x['reached'] for x in ch], 2)} "
                     f"| {_range([x['passive_drift'] for x in ch], 4)} | {hold} | {lift} | {bail} | {rejected} |")

    lines += [
        "",
        "## Masses and friction",
        "",
        "| category | densities (kg/m^3) | body mass (kg) | part mass (kg) | joint friction (N*m) | triangles per object |",
        "|---|---|---|---|---|---|",
    ]
    for c in CATEGORIES:
        recs = by_cat[c]
        body = [r["links"][r["body_link"]]["mass"] for r in recs]
        part = [r["links"][r["part_link"]]["mass"] for r in recs]
        dens = f"{recs[0]['links'][recs[0]['body_link']]['density']:g} / {recs[0]['links'][recs[0]['part_link']]['density']:g}"
        fric = [r["joint"]["friction"] for r in recs]
        tris = [sum(link["triangles"] for link in r["links"].values()) for r in recs]
        lines.append(f"| {c} | {dens} | {_range(body)} | {_range(part)} | {_range(fric, 2)} | {min(tris)}-{max(tris)} |")

    lines += ["", "## Split report", "",
              "Distance from each unseen object to its nearest seen object, next to the seen-to-seen nearest",
              "distances. *param*: RMS of parameter differences normalised by each parameter's full span (two",
              "independent uniform draws average about 0.4). *Chamfer*: symmetric Chamfer distance (mm) between",
              "2,000 surface samples of body + part at the reset angle (`dexart-lite objects split-report`).", ""]
    for c in CATEGORIES:
        seen = [i for i in infos if i.category == c and i.split == "seen"]
        unseen = [i for i in infos if i.category == c and i.split == "unseen"]
        lines += [split_report.category_report(c, seen, unseen).text(), ""]

    lines += ["## Montages", ""]
    lines += [f"* [{c}](montage_{c}.png)" for c in CATEGORIES]
    lines += ["", "Made with `dexart-lite objects montage --out-dir urdf/objects`; one object at a few angles:",
              "`dexart-lite objects show NAME --out show.png`.", "", "## Objects", ""]
    for c in CATEGORIES:
        keys = SPECS[c].summary_keys
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
