"""Point-cloud pretraining datasets: DAM (the task envs with random actions) and objects-only.

    dexart-lite data dam --task laptop --split all --samples-per-object 1000 --out data/dam_laptop --seed 0
    dexart-lite data objects --split all --samples-per-object 250 --out data/objects --seed 0
    dexart-lite data demos --task laptop --split seen --episodes-per-object 4 --noise 0.2 --out data/demos

(``demos``, scripted-expert demonstrations for distillation, lives in ``dexart_lite.demos``.)

**DAM** (DexArt's manipulation dataset, ``examples/pretrain/generate_dataset.py``): the task env
with point and camera noise (as the training env), random actions ``uniform(-2, 2)^22`` (the env
clips them to +-1, so about half the entries saturate, as in DexArt) and, before every step, the
object's task joint teleported to a uniform random state within its limits. A reset every 250
steps (``RESET_EVERY``) or when an episode ends. Each sample is the observation's 608 points
(512 observed + 96 imagined, robot-base frame) and the 4 labels of ``pointcloud.LABELS``:
0 functional part, 1 rest of the object, 2 hand, 3 arm.

**Objects-only** (stands in for the original's PartNet-Mobility set, which cannot be shipped): each
object of the four categories alone in a ``BulletSim`` (no robot, no table), placed where its task
puts it relative to the robot base (so its points are in the same robot-base frame as DAM and the
policy), the task joint at a uniform random state, and a ``DepthCamera`` at a random viewpoint
around it (``VIEW_*``). Per-point labels: 0 functional part, 1 rest; per-cloud: category and
template, for classification.

Layout on disk. ``--split seen`` writes ``OUT/seen/`` with parts ``train`` and ``val`` (separate
episodes / draws of the same seen objects, ``val_fraction`` of each object's samples); ``--split
unseen`` writes ``OUT/unseen/`` with the part ``test``; ``--split all`` both. Each split folder
holds ``manifest.json`` (kind, task, split, objects, counts, seed, settings, versions) and shards
``<part>-00000.npz`` (``np.savez_compressed``) of at most ``SHARD_SIZE`` samples:

    points  (S, N, 3) float16, m (rounding <= 0.25 mm for |x| < 1 m; the sensor's noise is 5 mm)
    labels  (S, N)    uint8, per-point labels
    object  (S,)      int16, index into the manifest's ``objects``
    joint   (S,)      float32, rad, the task joint when the cloud was taken

Everything is deterministic for a seed: object ``k`` of a split draws from
``np.random.default_rng([seed, split, k])``, and every episode's env reset is seeded from it.
"""

from __future__ import annotations

import argparse
import json
import math
import time
import zipfile
from dataclasses import asdict, dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from dexart_lite import objects as objects_lib
from dexart_lite import pointcloud as pc
from dexart_lite.registration import TASKS
from dexart_lite.utils import check_choice

MANIFEST = "manifest.json"
FORMAT = "dexart_lite.pretrain.dataset"
FORMAT_VERSION = 1
KINDS = ("dam", "objects")
SPLITS = ("seen", "unseen", "all")
PARTS = {"seen": ("train", "val"), "unseen": ("test",)}
SHARD_SIZE = 1000  # samples per shard file (about 4 MB for DAM clouds)
RESET_EVERY = 250  # DAM: env steps between resets (DexArt)
ACTION_RANGE = 2.0  # DAM: actions uniform(-2, 2), clipped to [-1, 1] by the env (DexArt)
DEFAULT_DAM_SAMPLES = 1000  # per object; DexArt used 8000 + 1000 (see benchmarks/results/pretraining)
DEFAULT_OBJECT_SAMPLES = 250  # per object
VAL_FRACTION = 1 / 9  # DexArt: 8000 train + 1000 val per seen object
SPLIT_CODE = {"seen": 0, "unseen": 1}  # enters the per-object seed
# Objects-only viewpoints, around the centre of the object's bounding box:
VIEW_ELEVATION = (math.radians(5), math.radians(60))  # rad above the horizontal
VIEW_DISTANCE = (1.1, 1.6)  # x the distance at which the bounding sphere just fills the field of view
VIEW_TARGET_JITTER = 0.1  # x the bounding radius, std of the look-at point's offset
OBJECT_LABELS = ("functional_part", "object")


# ----------------------------------------------------------------------------- configs
@dataclass
class DamConfig:
    """DAM generation: one task, seen and/or unseen objects."""

    task: str = field(default="laptop", metadata={"help": f"one of {', '.join(TASKS)}"})
    split: str = field(default="all", metadata={"help": "seen (train + val), unseen (test) or all"})
    samples_per_object: int = field(default=DEFAULT_DAM_SAMPLES, metadata={"help": "clouds per object (DexArt: 9000)"})
    out: str = field(default="data/dam", metadata={"help": "dataset folder (writes OUT/seen, OUT/unseen)"})
    seed: int = 0
    val_fraction: float = field(default=VAL_FRACTION, metadata={"help": "share of a seen object's samples for val"})
    num_points: int = field(default=512, metadata={"help": "observed points per cloud (+96 imagined)"})
    point_noise: bool = field(default=True, metadata={"help": "the sensor's point noise (as the training env)"})
    camera_noise: bool = field(default=True, metadata={"help": "per-reset camera perturbation (as the training env)"})
    objects: str | None = field(default=None, metadata={"help": "comma-separated object names instead of all"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})


@dataclass
class ObjectsConfig:
    """Objects-only generation: every object of the four categories, no robot."""

    split: str = field(default="all", metadata={"help": "seen (train + val), unseen (test) or all"})
    samples_per_object: int = field(default=DEFAULT_OBJECT_SAMPLES, metadata={"help": "clouds per object"})
    out: str = field(default="data/objects", metadata={"help": "dataset folder (writes OUT/seen, OUT/unseen)"})
    seed: int = 0
    val_fraction: float = field(default=VAL_FRACTION, metadata={"help": "share of a seen object's samples for val"})
    num_points: int = field(default=512, metadata={"help": "points per cloud"})
    categories: str = field(default=",".join(objects_lib.CATEGORIES), metadata={"help": "comma-separated"})
    objects: str | None = field(default=None, metadata={"help": "comma-separated object names instead of all"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})


def _names(value: str | None) -> list[str] | None:
    return [n.strip() for n in value.split(",") if n.strip()] if value else None


def _check_common(cfg) -> None:
    check_choice("split", cfg.split, SPLITS)
    if cfg.samples_per_object < 1 or cfg.num_points < 1:
        raise ValueError("samples_per_object and num_points must be >= 1")
    if not 0 <= cfg.val_fraction < 1:
        raise ValueError(f"val_fraction must be in [0, 1), got {cfg.val_fraction}")


def part_counts(split: str, samples: int, val_fraction: float) -> dict[str, int]:
    """Samples per object in each part: ``{"train": n - v, "val": v}`` (seen) or ``{"test": n}``."""
    if split == "unseen":
        return {"test": samples}
    val = min(samples - 1, max(1, round(samples * val_fraction))) if val_fraction > 0 and samples > 1 else 0
    return {"train": samples - val, "val": val}


def _versions() -> dict[str, str]:
    import dexart_lite

    out = {"dexart_lite": dexart_lite.__version__, "numpy": np.__version__}
    for package in ("pybullet",):
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "unknown"
    return out


# ----------------------------------------------------------------------------- writing
class ShardWriter:
    """Collects samples of one part and writes ``<part>-NNNNN.npz`` shards of ``SHARD_SIZE``."""

    def __init__(self, folder: Path, part: str):
        self.folder, self.part = folder, part
        self.shards: list[dict] = []
        self._buffer: list[tuple] = []
        self.count = 0

    def add(self, points: np.ndarray, labels: np.ndarray, obj: int, joint: float) -> None:
        """points (N, 3) m, labels (N,) in 0..3, obj index into the manifest's objects, joint rad."""
        self._buffer.append((points, labels, obj, joint))
        self.count += 1
        if len(self._buffer) == SHARD_SIZE:
            self.flush()

    def flush(self) -> None:
        if not self._buffer:
            return
        name = f"{self.part}-{len(self.shards):05d}.npz"
        points, labels, obj, joint = zip(*self._buffer)
        np.savez_compressed(self.folder / name, points=np.stack(points).astype(np.float16),
                            labels=np.stack(labels).astype(np.uint8), object=np.asarray(obj, np.int16),
                            joint=np.asarray(joint, np.float32))
        self.shards.append({"file": name, "count": len(self._buffer)})
        self._buffer = []


def _write_manifest(folder: Path, record: dict) -> Path:
    path = folder / MANIFEST
    path.write_text(json.dumps(record, indent=2) + "\n")
    return path


def _prepare(folder: Path) -> None:
    if (folder / MANIFEST).exists():
        raise ValueError(f"{folder} already holds a dataset; choose another --out or delete it")
    folder.mkdir(parents=True, exist_ok=True)


def _object_record(info: objects_lib.ObjectInfo) -> dict:
    return {"name": info.name, "category": info.category, "template": info.template,
            "joint_lower": info.joint_lower, "joint_upper": info.joint_upper}


def generate_dam(cfg: DamConfig) -> list[Path]:
    """Write the DAM dataset of ``cfg``; returns the manifest path of each split written."""
    from dexart_lite.envs import make

    check_choice("task", cfg.task, TASKS)
    _check_common(cfg)
    splits = ("seen", "unseen") if cfg.split == "all" else (cfg.split,)
    wanted = _names(cfg.objects)
    manifests = []
    for split in splits:
        infos = objects_lib.list_objects(cfg.task, split)
        if wanted is not None:
            infos = [i for i in infos if i.name in wanted]
            if not infos:
                continue
        folder = Path(cfg.out) / split
        _prepare(folder)
        counts = part_counts(split, cfg.samples_per_object, cfg.val_fraction)
        env = make(cfg.task, object_names=[i.name for i in infos], num_points=cfg.num_points,
                   point_noise=cfg.point_noise, camera_noise=cfg.camera_noise)
        scene = env.unwrapped
        total_points = scene.sensor_config.total_points  # observed + 96 imagined
        writers = {part: ShardWriter(folder, part) for part in counts}
        start, steps, resets = time.perf_counter(), 0, 0
        bar = tqdm(total=len(infos) * cfg.samples_per_object, unit="cloud", disable=not cfg.progress,
                   desc=f"DAM {cfg.task} {split}", dynamic_ncols=True)
        for k, info in enumerate(infos):
            rng = np.random.default_rng([cfg.seed, SPLIT_CODE[split], k])
            for part, count in counts.items():
                done, t = 0, RESET_EVERY  # t == RESET_EVERY forces a reset: parts never share an episode
                while done < count:
                    if t >= RESET_EVERY:
                        env.reset(seed=int(rng.integers(2**31)), options={"object": info.name})
                        t, resets = 0, resets + 1
                    scene.objects.set_joint(rng.uniform(info.joint_lower, info.joint_upper))
                    action = rng.uniform(-ACTION_RANGE, ACTION_RANGE, size=env.action_space.shape)
                    obs, _, terminated, truncated, step_info = env.step(action)
                    t, steps = t + 1, steps + 1
                    if terminated or truncated:
                        t = RESET_EVERY
                    labels = step_info["point_labels"]
                    if step_info["sim_unstable"] or labels.min() < 0:  # stale or empty view: not a sample
                        continue
                    writers[part].add(obs["point_cloud"], labels, k, scene.objects.joint_state()[0])
                    done += 1
                    bar.update(1)
        bar.close()
        env.close()
        for writer in writers.values():
            writer.flush()
        seconds = time.perf_counter() - start
        manifests.append(_write_manifest(folder, {
            "format": FORMAT, "format_version": FORMAT_VERSION, "kind": "dam", "task": cfg.task, "split": split,
            "seed": cfg.seed, "label_names": list(pc.LABELS), "num_points": total_points,
            "objects": [_object_record(i) for i in infos],
            "parts": {p: {"count": w.count, "shards": w.shards} for p, w in writers.items()},
            "settings": {k: v for k, v in asdict(cfg).items() if k not in ("out", "progress", "split")},
            "env_steps": steps, "resets": resets, "seconds": round(seconds, 1),
            "ms_per_sample": round(1000 * seconds / max(1, sum(w.count for w in writers.values())), 2),
            "versions": _versions()}))
    if not manifests:
        raise ValueError(f"none of the objects {wanted} is a {cfg.task} object")
    return manifests


def _bounding_sphere(sim, body) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius (m) of the axis-aligned bounding box of every link of ``body``."""
    lows, highs = [], []
    for link in [-1, *body.joints.values()]:
        low, high = sim.aabb(body, link)
        lows.append(low)
        highs.append(high)
    low, high = np.min(lows, axis=0), np.max(highs, axis=0)
    return (low + high) / 2, float(np.linalg.norm(high - low) / 2)


def random_viewpoint(rng: np.random.Generator, centre: np.ndarray, radius: float, fovy_deg: float):
    """A ``CameraPose`` looking at ``centre`` (jittered) from a random azimuth and elevation."""
    from dexart_lite.camera import CameraPose

    azimuth = rng.uniform(0, 2 * math.pi)
    elevation = rng.uniform(*VIEW_ELEVATION)
    distance = radius / math.sin(math.radians(fovy_deg) / 2) * rng.uniform(*VIEW_DISTANCE)
    direction = np.array([math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
                          math.sin(elevation)])
    target = centre + rng.normal(size=3) * VIEW_TARGET_JITTER * radius
    return CameraPose.look_at(centre + distance * direction, target)


def generate_objects(cfg: ObjectsConfig) -> list[Path]:
    """Write the objects-only dataset of ``cfg``; returns the manifest path of each split written."""
    from dexart_lite.articulated import PART_LINK, TASK_JOINT, yaw_quaternion
    from dexart_lite.camera import CameraIntrinsics, DepthCamera
    from dexart_lite.sim import BASE_LINK, BulletSim

    _check_common(cfg)
    categories = _names(cfg.categories) or []
    for category in categories:
        check_choice("category", category, objects_lib.CATEGORIES)
    wanted = _names(cfg.objects)
    splits = ("seen", "unseen") if cfg.split == "all" else (cfg.split,)
    intrinsics = CameraIntrinsics()
    manifests = []
    for split in splits:
        infos = [i for c in categories for i in objects_lib.list_objects(c, split)
                 if wanted is None or i.name in wanted]
        if not infos:
            continue
        folder = Path(cfg.out) / split
        _prepare(folder)
        counts = part_counts(split, cfg.samples_per_object, cfg.val_fraction)
        writers = {part: ShardWriter(folder, part) for part in counts}
        start = time.perf_counter()
        bar = tqdm(total=len(infos) * cfg.samples_per_object, unit="cloud", disable=not cfg.progress,
                   desc=f"objects {split}", dynamic_ncols=True)
        for k, info in enumerate(infos):
            rng = np.random.default_rng([cfg.seed, SPLIT_CODE[split], k])
            sim = BulletSim()  # one small world per object; physics is never stepped
            body = sim.load_urdf(info.name, info.urdf_path, position=info.position,
                                 orientation=yaw_quaternion(info.yaw), fixed_base=True)
            labels = pc.LabelTable()
            for link in [BASE_LINK, *body.joints.values()]:
                labels.set(body.uid, link, pc.FUNCTIONAL if link == PART_LINK else pc.OBJECT)
            camera = DepthCamera(sim, intrinsics, random_viewpoint(rng, np.zeros(3), 1.0, intrinsics.fovy_deg))
            for part, count in counts.items():
                done = 0
                while done < count:
                    q = rng.uniform(info.joint_lower, info.joint_upper)
                    sim.reset_joints(body, [TASK_JOINT], [q])
                    centre, radius = _bounding_sphere(sim, body)
                    camera.set_pose(random_viewpoint(rng, centre, radius, intrinsics.fovy_deg))
                    points, seg = camera.render()
                    point_labels = labels(seg)
                    keep = point_labels >= 0
                    idx = pc.sample_indices(int(keep.sum()), cfg.num_points, rng)
                    if len(idx) == 0:  # the jittered view missed the object: draw again
                        continue
                    writers[part].add(points[keep][idx], point_labels[keep][idx], k, q)
                    done += 1
                    bar.update(1)
            sim.close()
        bar.close()
        for writer in writers.values():
            writer.flush()
        seconds = time.perf_counter() - start
        manifests.append(_write_manifest(folder, {
            "format": FORMAT, "format_version": FORMAT_VERSION, "kind": "objects", "task": None, "split": split,
            "seed": cfg.seed, "label_names": list(OBJECT_LABELS), "num_points": cfg.num_points,
            "objects": [_object_record(i) for i in infos],
            "parts": {p: {"count": w.count, "shards": w.shards} for p, w in writers.items()},
            "settings": {k: v for k, v in asdict(cfg).items() if k not in ("out", "progress", "split")},
            "seconds": round(seconds, 1),
            "ms_per_sample": round(1000 * seconds / max(1, sum(w.count for w in writers.values())), 2),
            "versions": _versions()}))
    if not manifests:
        raise ValueError(f"no objects selected (categories {categories}, objects {wanted})")
    return manifests


# ----------------------------------------------------------------------------- reading
@dataclass
class PointCloudSet:
    """One part of a dataset, in memory. M clouds of N points."""

    points: torch.Tensor  # (M, N, 3) float32, m, robot-base frame
    labels: torch.Tensor  # (M, N) int64, per-point labels (``label_names``)
    object_index: torch.Tensor  # (M,) int64, index into ``objects``
    category: torch.Tensor  # (M,) int64, index into objects_lib.CATEGORIES
    template: torch.Tensor  # (M,) int64, 0 A, 1 B, 2 C
    objects: list[dict]  # the manifest's object records
    label_names: tuple[str, ...]
    kind: str  # "dam" or "objects"
    part: str

    def __len__(self) -> int:
        return self.points.shape[0]

    @property
    def num_classes(self) -> int:
        return len(self.label_names)

    def subset(self, index: torch.Tensor) -> PointCloudSet:
        return PointCloudSet(self.points[index], self.labels[index], self.object_index[index],
                             self.category[index], self.template[index], self.objects, self.label_names,
                             self.kind, self.part)


def read_manifest(folder: str | Path) -> dict:
    """The manifest of one split folder, checked; one-line errors for anything else."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise FileNotFoundError(f"no dataset manifest at {path} (make one with `dexart-lite data`)")
    try:
        record = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{path} is not a readable manifest ({err})") from None
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise ValueError(f"{path} is not a dexart_lite pretraining dataset manifest")
    if record.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{path} has format version {record.get('format_version')}, this code reads {FORMAT_VERSION}")
    return record


def find_part(root: str | Path, part: str) -> Path:
    """The split folder under ``root`` (or ``root`` itself) whose manifest has ``part``."""
    root = Path(root)
    candidates = [root] if (root / MANIFEST).exists() else [root / s for s in PARTS if (root / s / MANIFEST).exists()]
    if not candidates:
        raise FileNotFoundError(f"no dataset under {root}: expected {root}/seen/{MANIFEST} or {root}/unseen/{MANIFEST}")
    for folder in candidates:
        if part in read_manifest(folder)["parts"]:
            return folder
    raise FileNotFoundError(f"the dataset under {root} has no {part!r} part")


def has_part(root: str | Path, part: str) -> bool:
    try:
        find_part(root, part)
        return True
    except FileNotFoundError:
        return False


def _read_shard(path: Path, count: int, num_points: int) -> dict[str, np.ndarray]:
    """The arrays of one shard, checked against the manifest; ``ValueError`` naming the file otherwise."""
    if not path.is_file():
        raise FileNotFoundError(f"missing shard {path}")
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: npz[key] for key in ("points", "labels", "object", "joint")}
    except (zipfile.BadZipFile, ValueError, OSError, KeyError, EOFError) as err:
        reason = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise ValueError(f"corrupt shard {path} ({reason})") from None
    expected = {"points": (count, num_points, 3), "labels": (count, num_points), "object": (count,), "joint": (count,)}
    for key, shape in expected.items():
        if arrays[key].shape != shape:
            raise ValueError(f"corrupt shard {path}: {key} has shape {arrays[key].shape}, the manifest says {shape}")
    return arrays


def load_part(root: str | Path, part: str) -> PointCloudSet:
    """Part ``part`` ("train", "val" or "test") of the dataset under ``root``, as tensors."""
    folder = find_part(root, part)
    manifest = read_manifest(folder)
    entry, n = manifest["parts"][part], manifest["num_points"]
    chunks = [_read_shard(folder / s["file"], s["count"], n) for s in entry["shards"]]
    if sum(s["count"] for s in entry["shards"]) != entry["count"] or not chunks:
        raise ValueError(f"{folder / MANIFEST}: part {part!r} lists {entry['count']} samples in "
                         f"{len(chunks)} shards that do not add up")
    objects = manifest["objects"]
    object_index = torch.from_numpy(np.concatenate([c["object"] for c in chunks]).astype(np.int64))
    if object_index.min() < 0 or object_index.max() >= len(objects):
        raise ValueError(f"corrupt dataset {folder}: object indices outside the manifest's {len(objects)} objects")
    labels = torch.from_numpy(np.concatenate([c["labels"] for c in chunks]).astype(np.int64))
    if labels.max() >= len(manifest["label_names"]):
        raise ValueError(f"corrupt dataset {folder}: labels outside 0..{len(manifest['label_names']) - 1}")
    category = torch.tensor([objects_lib.CATEGORIES.index(o["category"]) for o in objects])[object_index]
    template = torch.tensor(["ABC".index(o["template"]) for o in objects])[object_index]
    return PointCloudSet(points=torch.from_numpy(np.concatenate([c["points"] for c in chunks]).astype(np.float32)),
                         labels=labels, object_index=object_index, category=category, template=template,
                         objects=objects, label_names=tuple(manifest["label_names"]), kind=manifest["kind"],
                         part=part)


# ----------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from dexart_lite.cli import add_config_arguments
    from dexart_lite import demos  # expert demonstrations for distillation (dexart_lite.imitation)

    sub = parser.add_subparsers(dest="kind", metavar="KIND", required=True)
    add_config_arguments(sub.add_parser("dam", help="the task env with random actions and joint states"), DamConfig)
    add_config_arguments(sub.add_parser("objects", help="the objects alone, random joint state and viewpoint"),
                         ObjectsConfig)
    demos.add_arguments(sub.add_parser("demos", help="scripted-expert demonstrations with executed-action noise"))


def run(args: argparse.Namespace) -> int:
    from dexart_lite.cli import config_from_args

    if args.kind == "demos":
        from dexart_lite import demos

        return demos.run(args)
    config_cls, generate = {"dam": (DamConfig, generate_dam), "objects": (ObjectsConfig, generate_objects)}[args.kind]
    cfg = config_from_args(config_cls, args)
    for path in generate(cfg):
        manifest = json.loads(path.read_text())
        counts = ", ".join(f"{p} {e['count']}" for p, e in manifest["parts"].items())
        print(f"{path}: {counts} clouds in {manifest['seconds']:.0f} s ({manifest['ms_per_sample']} ms per cloud)")
    return 0
