"""How far the unseen objects are from the seen ones.

Two distances per pair of objects of a category:

* **param**: RMS over the category's generator parameters of the difference divided by the
  parameter's full span (0 = identical parameters, ~0.4 = two independent uniform draws). A template
  change is not counted by itself, only through the parameters it changes.
* **chamfer**: symmetric Chamfer distance (mm) between 2,000 surface points of each object (body plus
  functional part at the reset angle, root frame), read from the committed OBJ files: the mean of the
  nearest-neighbour distances in both directions, averaged.

For every unseen object we report the distance to its nearest seen object; for reference, the
"seen-to-seen" numbers are each seen object's distance to its nearest other seen object.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from dexart_lite.objects import ObjectInfo, geometry
from dexart_lite.objects.generate import param_distance

SURFACE_POINTS = 2000


def posed_pieces(info: ObjectInfo, q: float) -> list:
    """Body and functional-part pieces in the root frame with the joint at ``q``."""
    record = json.loads((info.urdf_path.parent / "params.json").read_text())
    folder = info.urdf_path.parent
    body = geometry.read_obj_pieces(folder / f"{record['body_link']}.obj")
    part = geometry.read_obj_pieces(folder / f"{record['part_link']}.obj")
    joint = record["joint"]
    pose = np.eye(4)
    pose[:3, :3] = geometry.rpy_matrix(joint["origin_rpy"]) @ geometry.axis_rotation(joint["axis"], q)
    pose[:3, 3] = joint["origin_xyz"]
    return body + geometry.transform(part, pose)


def surface_points(info: ObjectInfo) -> np.ndarray:
    """``(SURFACE_POINTS, 3)`` surface samples at the reset angle (seeded by the object's name)."""
    seed = int(hashlib.sha256(info.name.encode()).hexdigest()[:8], 16)
    return geometry.surface_samples(posed_pieces(info, info.joint_init), SURFACE_POINTS, seed)


def chamfer_mm(a: np.ndarray, b: np.ndarray) -> float:
    d_ab = cKDTree(b).query(a)[0]
    d_ba = cKDTree(a).query(b)[0]
    return 1000.0 * 0.5 * (d_ab.mean() + d_ba.mean())


@dataclass
class Nearest:
    name: str
    template: str
    band: str  # "" or "<param> <kind>"
    param_dist: float
    param_nearest: str
    chamfer: float  # mm
    chamfer_nearest: str


@dataclass
class CategoryReport:
    category: str
    unseen: list[Nearest]
    seen: list[Nearest]  # each seen object vs the other seen objects

    def text(self) -> str:
        def stats(values):
            v = np.array(values)
            return f"median {np.median(v):.3f}, min {v.min():.3f}, max {v.max():.3f}"

        lines = [f"{self.category}: seen-to-seen nearest param distance {stats([n.param_dist for n in self.seen])}; "
                 f"Chamfer (mm) {stats([n.chamfer for n in self.seen])}",
                 "",
                 "| unseen object | template | held-out band | param dist to nearest seen | Chamfer (mm) to nearest seen |",
                 "|---|---|---|---|---|"]
        for n in self.unseen:
            lines.append(f"| {n.name} | {n.template} | {n.band or '-'} | {n.param_dist:.3f} ({n.param_nearest}) "
                         f"| {n.chamfer:.1f} ({n.chamfer_nearest}) |")
        return "\n".join(lines)


def _band_label(info: ObjectInfo) -> str:
    band = json.loads((info.urdf_path.parent / "params.json").read_text())["band"]
    return "" if band is None else f"{band['param']} {band['kind']} {band['fraction']}"


def category_report(category: str, seen: list[ObjectInfo], unseen: list[ObjectInfo]) -> CategoryReport:
    points = {info.name: surface_points(info) for info in seen + unseen}

    def nearest(info: ObjectInfo, pool: list[ObjectInfo]) -> Nearest:
        others = [o for o in pool if o.name != info.name]
        pd = [param_distance(category, info.params, o.params) for o in others]
        cd = [chamfer_mm(points[info.name], points[o.name]) for o in others]
        i, j = int(np.argmin(pd)), int(np.argmin(cd))
        return Nearest(info.name, info.template, _band_label(info), pd[i], others[i].name, cd[j], others[j].name)

    return CategoryReport(category, [nearest(u, seen) for u in unseen], [nearest(s, seen) for s in seen])
