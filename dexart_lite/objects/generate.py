"""Draw, check and write the committed object set: ``urdf/objects/<category>/<split>/<name>/``.

The recipe (``urdf/objects/README.md`` says what it produced):

* Seeds are fixed per (category, split, index, attempt): ``sha256("dexart_lite/objects/...")``, never
  Python's ``hash()``. Attempt k + 1 is drawn only when attempt k is rejected.
* Seen objects alternate templates A and B by index; their primary parameters avoid the held-out
  bands. Unseen objects: the first ceil(n / 2) use the held-out template C; the rest alternate A / B
  with one primary parameter drawn from a held-out band (interior 40-60 % or an outer 12 % of the
  range), the other parameters as for seen objects.
* The optional ``wide`` split (``CategorySpec.wide``; the toilet only): extra training objects of
  templates A / B, drawn as seen objects and then changed by the category's ``widen``. Drawn after the
  unseen objects, so a near-duplicate of any of them is rejected.
* A draw is rejected if it is a near-duplicate (normalised parameter distance < ``DUPLICATE_EPS``
  to an accepted object of the same template), if the grasp point leaves the arm's reach under
  DexArt's randomisation (``placement.py``), or if it fails a physics check (``feasibility.py``).
* An object is named ``<category>_<first 10 hex of sha1(canonical params)>``; the canonical params
  include ``GENERATOR_VERSION``, so names change whenever the geometry would. PyBullet caches meshes by
  path, so a folder is never rewritten with different content.

Everything written is a pure function of the seeds: regenerating reproduces the files byte for byte.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexart_lite.objects import bucket, faucet, feasibility, geometry, laptop, placement, toilet
from dexart_lite.objects.model import CategorySpec, ObjectModel, urdf_text
from dexart_lite.registration import SPECS as TASK_SPECS

GENERATOR_VERSION = 2  # bump whenever a generator's output changes for the same parameters
CATEGORY_SPECS: dict[str, CategorySpec] = {"faucet": faucet.SPEC, "bucket": bucket.SPEC, "laptop": laptop.SPEC,
                                           "toilet": toilet.SPEC}
SPLIT_SIZES = {c: {"seen": spec.seen, "unseen": spec.unseen} for c, spec in TASK_SPECS.items()}  # DexArt's
WIDE_SIZES = {c: spec.wide for c, spec in CATEGORY_SPECS.items()}  # extra training objects (not DexArt's)
GENERATED_SPLITS = ("seen", "unseen", "wide")  # in drawing order
DUPLICATE_EPS = 0.08  # normalised parameter distance below which a draw is a near-duplicate
MAX_ATTEMPTS = 200
NAME_PATTERN = re.compile(r"^(faucet|bucket|laptop|toilet)_[0-9a-f]{10}$")
CHECKS_FILE = "checks.json"


@dataclass(frozen=True)
class Band:
    """A held-out band of one primary parameter, as fractions of its A/B range."""

    param: str
    lo: float
    hi: float

    @property
    def kind(self) -> str:
        return "interior" if 0.0 < self.lo and self.hi < 1.0 else "outer"


@dataclass
class Draw:
    """One attempt: template, parameters and the model built from them."""

    category: str
    split: str
    index: int
    attempt: int
    seed: int
    template: str
    band: Band | None
    params: dict
    model: ObjectModel
    name: str


def seed_for(category: str, split: str, index: int, attempt: int) -> int:
    digest = hashlib.sha256(f"dexart_lite/objects/{category}/{split}/{index}/{attempt}".encode()).hexdigest()
    return int(digest[:16], 16)


def template_and_band(category: str, split: str, index: int) -> tuple[str, Band | None]:
    """The template (and held-out band, if any) of the object at ``index`` of a split."""
    if split in ("seen", "wide"):
        return "AB"[index % 2], None
    n_template_c = math.ceil(SPLIT_SIZES[category]["unseen"] / 2)
    if index < n_template_c:
        return "C", None
    k = index - n_template_c
    spec = CATEGORY_SPECS[category]
    p1, p2 = spec.primary
    # Cycle (p1, interior), (p2, outer), (p1, outer), (p2, interior) so few objects cover all four.
    param, band_i = [(p1, 0), (p2, 1), (p1, 1), (p2, 0)][k % 4]
    lo, hi = spec.param(param).heldout[band_i]
    return "AB"[k % 2], Band(param, lo, hi)


def _allowed_fraction(rng: np.random.Generator, bands) -> float:
    """A uniform draw from [0, 1] minus the held-out ``bands``."""
    edges, start = [], 0.0
    for lo, hi in sorted(bands):
        if lo > start:
            edges.append((start, lo))
        start = max(start, hi)
    if start < 1.0:
        edges.append((start, 1.0))
    lengths = np.array([b - a for a, b in edges])
    u = rng.uniform(0.0, lengths.sum())
    for (a, _), length in zip(edges, lengths):
        if u <= length:
            return a + u
        u -= length
    return edges[-1][1]


def draw_params(category: str, split: str, index: int, attempt: int) -> tuple[str, Band | None, dict, int]:
    """Template, band, parameters and seed of one attempt (pure function of its arguments)."""
    spec = CATEGORY_SPECS[category]
    template, band = template_and_band(category, split, index)
    seed = seed_for(category, split, index, attempt)
    rng = np.random.default_rng(seed)
    params = {}
    for param in spec.params:
        lo, hi = param.ranges[template]
        if band is not None and param.name == band.param:
            u = rng.uniform(band.lo, band.hi)
        elif template != "C" and param.heldout:
            u = _allowed_fraction(rng, param.heldout)
        else:
            u = rng.uniform(0.0, 1.0)
        params[param.name] = round(lo + u * (hi - lo), param.decimals) + 0.0
    if split == "wide":
        params = spec.widen(params, rng)
    return template, band, params, seed


def canonical_json(category: str, template: str, params: dict) -> str:
    payload = {"category": category, "template": template, "params": params, "version": GENERATOR_VERSION}
    return json.dumps(payload, sort_keys=True, separators=(",", ":"))


def object_name(category: str, template: str, params: dict) -> str:
    return f"{category}_{hashlib.sha1(canonical_json(category, template, params).encode()).hexdigest()[:10]}"


def make_draw(category: str, split: str, index: int, attempt: int) -> Draw:
    template, band, params, seed = draw_params(category, split, index, attempt)
    model = CATEGORY_SPECS[category].build(template, params)
    return Draw(category, split, index, attempt, seed, template, band, params, model,
                object_name(category, template, params))


def param_distance(category: str, a: dict, b: dict) -> float:
    """RMS over the category's parameters of the difference normalised by each parameter's span."""
    terms = []
    for param in CATEGORY_SPECS[category].params:
        lo, hi = param.span()
        if hi > lo:
            terms.append(((a[param.name] - b[param.name]) / (hi - lo)) ** 2)
    return float(math.sqrt(sum(terms) / len(terms)))


def _r(x, digits: int = 6):
    """Round floats (also inside lists) for a stable params.json."""
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_r(v, digits) for v in x]
    return round(float(x), digits) + 0.0


def _u(x):
    """A float (or list of floats) exactly as the URDF writes it."""
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_u(v) for v in x]
    return float(geometry.fmt(x))


def record(draw: Draw, place: placement.Placement) -> dict:
    """The params.json content of an accepted draw (geometry-derived only, no physics results)."""
    m, j = draw.model, draw.model.joint
    links = {}
    for link in (m.body, m.part):
        props = link.mass_properties()
        links[link.name] = {"mass": _u(props.mass), "density": link.density, "com": _u(props.com),
                            "volume": _r(props.volume, 9), "pieces": len(link.pieces), "triangles": link.triangles()}
    return {
        "name": draw.name,
        "category": draw.category,
        "split": draw.split,
        "index": draw.index,
        "template": draw.template,
        "band": None if draw.band is None else {"param": draw.band.param, "fraction": [draw.band.lo, draw.band.hi],
                                                "kind": draw.band.kind},
        "seed": {"attempt": draw.attempt, "value": draw.seed},
        "generator_version": GENERATOR_VERSION,
        "urdf": f"{draw.name}.urdf",
        "fixed_base": m.fixed_base,
        "body_link": m.body.name,
        "part_link": m.part.name,
        "joint": {"name": j.name, "index": 0, "origin_xyz": _u(j.xyz), "origin_rpy": _u(j.rpy), "axis": _u(j.axis),
                  "lower": _u(j.lower), "upper": _u(j.upper), "init": _u(j.init), "target": _u(j.target),
                  "friction": _u(j.friction)},
        "grasp_point": _r(m.grasp_point),
        "placement": {"position": _r(place.position), "yaw": _r(place.yaw), "reach_margin": place.reach_margin,
                      "grasp_nominal": _r(place.grasp_nominal)},
        "links": links,
        "derived": {k: _r(v) for k, v in sorted(m.notes.items())},
        "params": draw.params,
    }


def write_object(folder: Path, draw: Draw, rec: dict) -> None:
    """Write the URDF, one OBJ per link and params.json into ``folder`` (created)."""
    folder.mkdir(parents=True, exist_ok=True)
    m = draw.model
    for link in (m.body, m.part):
        (folder / f"{link.name}.obj").write_text(geometry.obj_text(link.pieces, f"{draw.name} link {link.name}"))
    (folder / f"{draw.name}.urdf").write_text(urdf_text(m, draw.name))
    (folder / "params.json").write_text(json.dumps(rec, indent=1) + "\n")


@dataclass
class Accepted:
    draw: Draw
    record: dict
    checks: dict  # feasibility.CheckResult.as_dict()
    rejected: dict  # reason -> count, for the attempts before this one


def generate_split(category: str, split: str, accepted: list[Accepted], staging: Path, log=print) -> list[Accepted]:
    """Draw the objects of one split; ``accepted`` (earlier objects of the category) is extended."""
    out = []
    size = WIDE_SIZES[category] if split == "wide" else SPLIT_SIZES[category][split]
    for index in range(size):
        rejected: dict[str, int] = {}
        for attempt in range(MAX_ATTEMPTS):
            draw = make_draw(category, split, index, attempt)
            twins = [a for a in accepted if a.draw.template == draw.template
                     and param_distance(category, a.draw.params, draw.params) < DUPLICATE_EPS]
            if twins:
                rejected["near-duplicate"] = rejected.get("near-duplicate", 0) + 1
                continue
            place = placement.choose_placement(draw.model)
            if place.reach_margin < 0:
                rejected["out of reach"] = rejected.get("out of reach", 0) + 1
                continue
            rec = record(draw, place)
            folder = staging / category / split / draw.name
            write_object(folder, draw, rec)
            result = feasibility.check(folder / rec["urdf"], category, rec["joint"], rec["grasp_point"],
                                       rec["fixed_base"])
            if result.failures:
                reason = "physics: " + result.failures[0].split(" ")[0]
                rejected[reason] = rejected.get(reason, 0) + 1
                shutil.rmtree(folder)
                continue
            item = Accepted(draw, rec, result.as_dict(), rejected)
            accepted.append(item)
            out.append(item)
            log(f"{category:6s} {split:6s} {index:2d} {draw.template} {draw.name} attempt {attempt}"
                + (f" (rejected: {rejected})" if rejected else ""))
            break
        else:
            raise RuntimeError(f"{category}/{split}/{index}: no feasible draw in {MAX_ATTEMPTS} attempts ({rejected})")
    return out


def generate_category(category: str, staging: Path, log=print) -> list[Accepted]:
    accepted: list[Accepted] = []
    for split in GENERATED_SPLITS:
        generate_split(category, split, accepted, staging, log)
    return accepted


def _existing_folders(root: Path, category: str) -> list[Path]:
    found = []
    for split in GENERATED_SPLITS:
        base = root / category / split
        if base.is_dir():
            found += [d for d in sorted(base.iterdir())
                      if d.is_dir() and not d.is_symlink() and NAME_PATTERN.match(d.name) and (d / "params.json").is_file()]
    return found


def _same_tree(a: Path, b: Path) -> bool:
    files_a = sorted(p.name for p in a.iterdir())
    files_b = sorted(p.name for p in b.iterdir())
    return files_a == files_b and all((a / f).read_bytes() == (b / f).read_bytes() for f in files_a)


def generate(root: Path, categories=tuple(CATEGORY_SPECS), log=print) -> dict[str, list[Accepted]]:
    """Regenerate ``categories`` into ``root`` (e.g. ``urdf/objects``).

    Objects whose folder already exists are left untouched (after checking that the bytes agree: a
    mismatch means the generator changed without a ``GENERATOR_VERSION`` bump, and is an error).
    New objects are copied in; object folders of these categories that are no longer in the set are
    removed. Only folders named like ``<category>_<10 hex>`` holding a params.json are ever removed.
    Also writes ``checks.json`` (the physics measurements of every object in ``root``).
    """
    root = Path(root)
    results = {}
    with tempfile.TemporaryDirectory(prefix="dexart_lite_objects_") as tmp:
        staging = Path(tmp)
        for category in categories:
            results[category] = generate_category(category, staging, log)
        for category in categories:
            keep = set()
            for item in results[category]:
                src = staging / category / item.draw.split / item.draw.name
                dst = root / category / item.draw.split / item.draw.name
                keep.add(dst)
                if dst.exists():
                    if not _same_tree(src, dst):
                        raise RuntimeError(f"{dst} exists with different content: bump GENERATOR_VERSION")
                    continue
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copytree(src, dst)
                log(f"wrote {dst}")
            for folder in _existing_folders(root, category):
                if folder not in keep:
                    shutil.rmtree(folder)
                    log(f"removed stale {folder}")
    checks_path = root / CHECKS_FILE
    checks = json.loads(checks_path.read_text()) if checks_path.is_file() else {}
    checks = {name: value for name, value in checks.items() if name.split("_")[0] not in categories}
    for category in categories:
        for item in results[category]:
            checks[item.draw.name] = {"checks": item.checks, "rejected_before": item.rejected}
    checks_path.write_text(json.dumps(dict(sorted(checks.items())), indent=1) + "\n")
    return results
