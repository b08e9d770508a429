"""The articulated objects of dexart_lite: a catalog over the committed, procedurally generated set.

Each object lives in ``urdf/objects/<category>/<split>/<name>/`` (``<name>.urdf``, one OBJ per link,
``params.json``). The catalog reads only the ``params.json`` files; nothing is generated at load time.

Conventions shared by every object (details in each generator's docstring and in
``urdf/objects/README.md``):

* Two links: the root **body** (link index -1) and the **functional part** (link index 0), joined by
  the task's revolute joint (joint index 0).
* Root frame: origin at the centre of the object's footprint, z = 0 at its bottom. The functional part
  faces -x, where the robot stands.
* Load with ``flags=URDF_USE_INERTIA_FROM_FILE`` (otherwise PyBullet recomputes the inertia from the
  collision shapes' bounding boxes) and apply ``joint_friction`` as a ``VELOCITY_CONTROL`` motor with
  target velocity 0 and ``force=joint_friction`` (this also replaces PyBullet's default joint motor).

Example::

    from dexart_lite.objects import list_objects
    for info in list_objects("laptop", "seen_half"):
        print(info.name, info.urdf_path, info.joint_target)
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path

from dexart_lite import paths
from dexart_lite.registration import SPECS, TASKS
from dexart_lite.utils import check_choice

CATEGORIES = TASKS
# seen_half = the first 5/5/5/8 seen objects (by index); wide = extra training objects of templates A / B drawn
# beyond their seen ranges (toilets only, ``CategorySpec.widen``); seen_wide = seen + wide. Only seen and unseen
# are DexArt's splits, and only they are evaluated.
SPLITS = ("seen", "unseen", "seen_half", "wide", "seen_wide")
TRAINING_SPLITS = ("seen", "seen_half", "seen_wide")  # what a learner may train on
FOLDERS = ("seen", "unseen", "wide")  # urdf/objects/<category>/<folder>/
HALF_SIZES = {c: SPECS[c].half for c in CATEGORIES}  # registration.SPECS: the tasks' facts, written once
ROBOT_BASE = {c: SPECS[c].robot_base for c in CATEGORIES}  # world, metres (DexArt)


@dataclass(frozen=True)
class ObjectInfo:
    """One committed object, as recorded in its ``params.json``."""

    name: str
    category: str
    split: str  # "seen", "unseen" or "wide" (seen_half objects are seen objects)
    index: int  # position in its split
    template: str  # "A" or "B" (seen, wide), "A", "B" or "C" (unseen); C is the held-out template
    urdf_path: Path  # absolute
    fixed_base: bool  # False only for bucket
    joint_name: str  # the task joint; it is joint index 0 and the functional part is link index 0
    joint_lower: float  # rad
    joint_upper: float  # rad
    joint_init: float  # rad, the state at reset
    joint_target: float  # rad, DexArt's "middle"
    joint_friction: float  # N*m, VELOCITY_CONTROL motor force applied by the task
    position: tuple[float, float, float]  # m, nominal root position relative to the robot base (world axes)
    yaw: float  # rad, nominal root yaw (the task adds DexArt's randomisation on top)
    grasp_point: tuple[float, float, float]  # m, the "handle point" in the functional part's link frame
    params: dict  # the generator parameters (dimensions etc.)


def _info(record: dict, folder: Path) -> ObjectInfo:
    joint = record["joint"]
    return ObjectInfo(
        name=record["name"], category=record["category"], split=record["split"], index=record["index"],
        template=record["template"], urdf_path=(folder / record["urdf"]).resolve(),
        fixed_base=record["fixed_base"], joint_name=joint["name"], joint_lower=joint["lower"],
        joint_upper=joint["upper"], joint_init=joint["init"], joint_target=joint["target"],
        joint_friction=joint["friction"], position=tuple(record["placement"]["position"]),
        yaw=record["placement"]["yaw"], grasp_point=tuple(record["grasp_point"]), params=dict(record["params"]),
    )


@functools.lru_cache(maxsize=4)
def _catalog(root: str) -> dict[str, dict[str, list[ObjectInfo]]]:
    """``{category: {"seen": [...], "unseen": [...], "wide": [...]}}`` read from the params.json files under
    ``root``."""
    catalog: dict[str, dict[str, list[ObjectInfo]]] = {c: {s: [] for s in FOLDERS} for c in CATEGORIES}
    for category in CATEGORIES:
        for split in FOLDERS:
            folder = Path(root) / category / split
            if not folder.is_dir():
                continue
            infos = [_info(json.loads(f.read_text()), f.parent) for f in sorted(folder.glob("*/params.json"))]
            catalog[category][split] = sorted(infos, key=lambda info: info.index)
    return catalog


def _objects_root() -> str:
    return str(paths.objects_dir())


def list_objects(category: str, split: str) -> list[ObjectInfo]:
    """The objects of ``category`` in ``split``, ordered by index."""
    check_choice("category", category, CATEGORIES)
    check_choice("split", split, SPLITS)
    catalog = _catalog(_objects_root())[category]
    if split == "seen_half":
        return catalog["seen"][: HALF_SIZES[category]]
    if split == "seen_wide":
        return catalog["seen"] + catalog["wide"]
    return list(catalog[split])


def all_objects(root: Path | None = None) -> list[ObjectInfo]:
    """Every object, by category, split (seen, unseen, wide) and index; ``root`` defaults to ``urdf/objects``."""
    catalog = _catalog(str(Path(root).resolve()) if root is not None else _objects_root())
    return [info for c in CATEGORIES for s in FOLDERS for info in catalog[c][s]]


def get_object(name: str) -> ObjectInfo:
    """The object called ``name`` (e.g. ``"laptop_0123456789"``)."""
    objects = all_objects()
    for info in objects:
        if info.name == name:
            return info
    prefix = str(name).split("_")[0]
    same_category = [info.name for info in objects if info.category == prefix]
    if same_category:
        check_choice(f"{prefix} object", name, same_category)  # raises, listing that category's names
    raise ValueError(f"unknown object {name!r}; names are <category>_<10 hex digits> with category one of: "
                     f"{', '.join(CATEGORIES)} (`dexart-lite objects list` prints them all)")
