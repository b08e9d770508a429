"""Scripted-expert demonstrations: noisy executed actions, clean expert labels, a memmapped folder.

    dexart-lite data demos --task laptop --split seen --episodes-per-object 4 --noise 0.2 --seed 0 --out data/demos

The expert (``experts.ScriptedPolicy``, which reads the simulator's privileged state) is queried on
every step. Gaussian noise of std ``noise`` is added to the action it returns and the result,
clipped to [-1, 1], is what the env executes; the clean expert action is the label. The noise takes
the hand off the expert's own path, so the labels also cover states near it (DART-style noise
injection; DAgger in ``distill.py`` goes further and lets the student drive).

Episodes run in rounds of one per object (all objects once, then again), each reset with its own
seed drawn from ``seed``; the noise has its own generator, also seeded from ``seed``: the same seed
writes the same bytes.

Layout of ``OUT``:

    manifest.json          format, version, task, split, objects, seed, noise, counts, per-episode
                           results, the expert's success rate, package versions, wall time
    samples/               a ``TensorDict.memmap`` folder (meta.json + one .memmap file per key)

One sample per env step (``S`` samples, ``N`` = observed + 96 imagined points, ``D`` = state size):

    point_cloud    (S, N, 3) float32   the observation the expert acted on, robot-base frame, m
    imagined_mask  (S, N) int8         1 for imagined hand points
    observation    (S, D) float32      the env's "state" vector (torchrl's name for it, as in PPO batches)
    expert_action  (S, 22) float32     the label: the clean expert action on that observation
    action         (S, 22) float64     the action executed (label + noise, clipped), exactly as the env ran it
    stage          (S,) int64          the stage after the step (1 reach, 2 contact, 3 manipulate)
    success        (S,) bool           success after the step
    object         (S,) int64          index into the manifest's ``objects``
    episode        (S,) int64          episode index (order of collection)
    t              (S,) int64          step within the episode (0: the reset observation)
    privileged     (S, 20) float32     the expert's view of the object (``experts.Solver.privileged``:
                                       part pose, joint angle and target, extent, grasp point); zeros
                                       for an expert without one. Distillation's auxiliary target.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from importlib import metadata
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict

from dexart_lite import objects as objects_lib
from dexart_lite.registration import PRIVILEGED_DIM, TASKS
from dexart_lite.rollout import noisy, per_object_summary, run_episodes
from dexart_lite.utils import check_choice

FORMAT = "dexart_lite.demos"
FORMAT_VERSION = 3  # 2: + privileged; 3: action stored as float64
MANIFEST = "manifest.json"
SAMPLES = "samples"  # the TensorDict.memmap folder inside OUT
SPLITS = (*objects_lib.TRAINING_SPLITS, "unseen")  # the training splits, and the unseen one for analyses
MANIFEST_KEYS = ("task", "split", "objects", "num_points", "cloud_points", "state_dim", "samples", "episodes",
                 "expert_success_rate", "expert_mean_max_stage", "noise", "seed")
ACTION_DIM = 22
# key -> (shape after the sample dimension, with N / D for the cloud and state sizes; dtype)
SAMPLE_SPECS = {
    "point_cloud": (("N", 3), torch.float32),
    "imagined_mask": (("N",), torch.int8),
    "observation": (("D",), torch.float32),
    "expert_action": ((ACTION_DIM,), torch.float32),
    "action": ((ACTION_DIM,), torch.float64),  # float64: exactly what the env ran, so a replay is exact
    "stage": ((), torch.int64),
    "success": ((), torch.bool),
    "object": ((), torch.int64),
    "episode": ((), torch.int64),
    "t": ((), torch.int64),
    "privileged": ((PRIVILEGED_DIM,), torch.float32),
}
# with depth images (the 2-D baseline, manifest "depth_image": true), one more key:
#   depth_image    (S, 64, 64) float32   the camera's metric depth image of the same frame, m (0: no hit)
IMAGE_SPECS = {"depth_image": ((64, 64), torch.float32)}


def sample_specs(manifest: dict) -> dict:
    """The keys of a demonstrations folder: ``SAMPLE_SPECS``, plus ``IMAGE_SPECS`` if it holds images."""
    return {**SAMPLE_SPECS, **(IMAGE_SPECS if manifest.get("depth_image") else {})}


class Recorder:
    """An ``on_step`` hook for ``rollout.run_episodes``: one sample per step.

    ``labelled`` is the policy being run; after each call its ``label`` attribute holds the expert
    action for the observation it was called on (``rollout.Noisy``, ``distill.Mixture``).
    """

    def __init__(self, labelled, objects: list[str], first_episode: int = 0):
        self.labelled = labelled
        self.object_index = {name: i for i, name in enumerate(objects)}
        self.episode = first_episode - 1
        self.rows: list[tuple] = []
        self.images: list[np.ndarray] = []  # depth images, when the env observes them

    def __call__(self, obs, action, reward, next_obs, info, t) -> None:
        if t == 0:
            self.episode += 1
        self.rows.append((np.array(obs["point_cloud"], np.float32), np.array(obs["imagined_mask"], np.int8),
                          np.array(obs["state"], np.float32), np.array(self.labelled.label, np.float32),
                          np.clip(np.asarray(action, np.float64), -1.0, 1.0), int(info["stage"]),
                          bool(info["success"]), self.object_index[info["object_name"]], self.episode, t,
                          np.zeros(PRIVILEGED_DIM, np.float32) if getattr(self.labelled, "privileged", None) is None
                          else np.asarray(self.labelled.privileged, np.float32)))
        if "depth_image" in obs:
            self.images.append(np.array(obs["depth_image"], np.float32))

    def samples(self) -> TensorDict:
        """The recorded steps as a ``TensorDict`` of batch size ``[S]`` (keys: ``SAMPLE_SPECS``)."""
        if not self.rows:
            raise ValueError("no steps were recorded")
        columns = [torch.as_tensor(np.stack(column)) for column in zip(*self.rows)]
        data = {key: column.to(dtype) for (key, (_, dtype)), column in zip(SAMPLE_SPECS.items(), columns)}
        if self.images:
            data["depth_image"] = torch.as_tensor(np.stack(self.images))
        return TensorDict(data, batch_size=[len(self.rows)])


def episode_list(names: list[str], episodes_per_object: int, rng: np.random.Generator) -> list[tuple[int, str]]:
    """``(seed, object)`` pairs in rounds of one episode per object, seeds drawn from ``rng``."""
    seeds = rng.integers(2**31, size=episodes_per_object * len(names))
    return [(int(seeds[k * len(names) + i]), name) for k in range(episodes_per_object) for i, name in enumerate(names)]


def package_versions() -> dict[str, str]:
    out = {}
    for package in ("dexart_lite", "torch", "torchrl", "tensordict", "pybullet", "numpy"):
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "unknown"
    return out


def collect_demos(task: str, split: str, episodes_per_object: int, noise: float, seed: int, out: str | Path,
                  num_points: int = 512, max_episode_steps: int | None = None, object_names: list[str] | None = None,
                  progress: bool = True, camera_noise: bool = True, imagination: bool = True,
                  view_range: tuple[float, float] | None = None, depth_image: bool = False) -> dict:
    """Run the noisy expert on every object of ``split`` and write ``out`` (see the module docstring);
    returns the manifest. ``camera_noise``: DexArt's per-reset camera perturbation (on, as in training);
    ``imagination``: the 96 imagined hand points in the cloud (on, as in DexArt); ``view_range``: random
    camera viewpoints, (azimuth, polar) half-widths in degrees (the env's keyword; None: fixed camera);
    ``depth_image``: also store the camera's depth image of every step (``IMAGE_SPECS``)."""
    from dexart_lite.envs import make
    from dexart_lite.experts import ScriptedPolicy

    check_choice("task", task, TASKS)
    check_choice("split", split, SPLITS)
    for name, value in (("episodes_per_object", episodes_per_object), ("num_points", num_points)):
        if value < 1:
            raise ValueError(f"{name} must be >= 1, got {value}")
    if not (math.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise must be a finite std >= 0, got {noise}")
    out = Path(out)
    if (out / MANIFEST).exists():
        raise ValueError(f"{out} already holds demonstrations; choose another --out or delete it")
    in_split = [info.name for info in objects_lib.list_objects(task, split)]
    names = list(object_names) if object_names else in_split
    for name in names:
        check_choice(f"{split} {task} object", name, in_split)

    start = time.perf_counter()
    env = make(task, split=split, object_names=names, num_points=num_points, point_noise=True, camera_noise=camera_noise,
               max_episode_steps=max_episode_steps, imagination=imagination, view_range=view_range,
               depth_image=depth_image)
    expert = noisy(ScriptedPolicy(env), noise, np.random.default_rng([seed, 1]))
    recorder = Recorder(expert, names)
    episodes = episode_list(names, episodes_per_object, np.random.default_rng([seed, 0]))
    try:
        results = run_episodes(expert, env, episodes, on_step=recorder, progress=progress)
    finally:
        env.close()
    samples = recorder.samples()
    summary = per_object_summary(results)
    manifest = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "task": task, "split": split, "objects": names,
        "seed": seed, "noise": noise, "camera_noise": camera_noise, "imagination": imagination,
        "view_range": list(view_range) if view_range is not None else None, "depth_image": bool(depth_image),
        "episodes_per_object": episodes_per_object, "num_points": num_points,
        "cloud_points": samples["point_cloud"].shape[1], "state_dim": samples["observation"].shape[1],
        "max_episode_steps": max_episode_steps, "samples": samples.batch_size[0],
        "expert_success_rate": summary["success_rate"], "expert_mean_max_stage": summary["mean_max_stage"],
        "expert_per_object": {n: r["success_rate"] for n, r in summary["objects"].items()},
        "episodes": [{k: e[k] for k in ("object", "seed", "success", "max_stage", "return", "steps")} for e in results],
        "versions": package_versions(), "wall_time_s": round(time.perf_counter() - start, 1),
    }
    write_demos(samples, out, manifest)
    return manifest


def write_demos(samples: TensorDict, out: str | Path, manifest: dict) -> Path:
    """Memmap ``samples`` into ``out/samples`` and write ``out/manifest.json`` last (a folder without
    a manifest is an unfinished one)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    samples.memmap(str(out / SAMPLES))
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return out


def read_manifest(path: str | Path) -> dict:
    """The checked manifest of a demonstrations folder; one-line errors otherwise."""
    path = Path(path)
    if not path.is_dir():
        raise FileNotFoundError(f"no demonstrations folder at {path} (make one with `dexart-lite data demos`)")
    file = path / MANIFEST
    if not file.is_file():
        raise FileNotFoundError(f"{path} has no {MANIFEST}: not a demonstrations folder, or an unfinished one")
    try:
        manifest = json.loads(file.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ValueError(f"{file} is not a readable manifest ({err})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise ValueError(f"{file} is not a dexart_lite demonstrations manifest (written by `dexart-lite data demos`)")
    if manifest.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{file} has format version {manifest.get('format_version')}, "
                         f"this code reads {FORMAT_VERSION}")
    missing = [key for key in MANIFEST_KEYS if key not in manifest]
    if missing:
        raise ValueError(f"{file} is an incomplete demonstrations manifest: it lacks {missing}")
    return manifest


def load_demos(path: str | Path) -> TensorDict:
    """The samples of a demonstrations folder, memory-mapped (batch size ``[S]``, keys ``SAMPLE_SPECS``);
    ``FileNotFoundError`` / ``ValueError`` in one line for a missing, corrupt or foreign folder."""
    path = Path(path)
    manifest = read_manifest(path)
    specs = sample_specs(manifest)
    sizes = {"N": manifest["cloud_points"], "D": manifest["state_dim"]}
    shapes = {key: (manifest["samples"], *(sizes.get(d, d) for d in shape)) for key, (shape, _) in specs.items()}
    # load_memmap skips missing files and maps truncated ones without a word: check the files first
    for key, (_, dtype) in specs.items():
        file = path / SAMPLES / f"{key}.memmap"
        expected = math.prod(shapes[key]) * dtype.itemsize
        if not file.is_file() or file.stat().st_size != expected:
            found = f"{file.stat().st_size} bytes" if file.is_file() else "missing"
            raise ValueError(f"corrupt demonstrations {path}: {file.name} is {found}, the manifest implies "
                             f"{shapes[key]} {dtype} ({expected} bytes)")
    try:
        samples = TensorDict.load_memmap(str(path / SAMPLES))
    except Exception as err:  # missing or unreadable meta.json, ...
        detail = " ".join(str(err).split()) or type(err).__name__
        raise ValueError(f"corrupt demonstrations {path / SAMPLES} ({detail[:200]})") from None
    for key, (_, dtype) in specs.items():
        if key not in samples.keys() or tuple(samples[key].shape) != shapes[key] or samples[key].dtype != dtype:
            found = f"{tuple(samples[key].shape)} {samples[key].dtype}" if key in samples.keys() else "missing"
            raise ValueError(f"corrupt demonstrations {path}: {key} is {found} in meta.json, the manifest says "
                             f"{shapes[key]} {dtype}")
    return samples


# ----------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of ``dexart-lite data demos``."""
    parser.add_argument("--task", default="laptop", help=f"one of {', '.join(TASKS)}")
    parser.add_argument("--split", default="seen", help=f"objects: {', '.join(SPLITS)}")
    parser.add_argument("--episodes-per-object", type=int, default=4, help="expert episodes per object")
    parser.add_argument("--noise", type=float, default=0.2, help="std of the executed-action noise (labels stay clean)")
    parser.add_argument("--seed", type=int, default=0, help="seeds the episodes and the noise")
    parser.add_argument("--out", required=True, help="folder to write (manifest.json + samples/)")
    parser.add_argument("--num-points", type=int, default=512, help="observed points per cloud (+96 imagined)")
    parser.add_argument("--max-episode-steps", type=int, default=None, help="episode length (default: the task's 250)")
    parser.add_argument("--objects", default=None, help="comma-separated object names instead of the whole split")
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=True, help="show a progress bar")


def run(args: argparse.Namespace) -> int:
    names = [n.strip() for n in args.objects.split(",") if n.strip()] if args.objects else None
    manifest = collect_demos(args.task, args.split, args.episodes_per_object, args.noise, args.seed, args.out,
                             args.num_points, args.max_episode_steps, names, args.progress)
    print(f"{args.out}: {manifest['samples']} samples from {len(manifest['episodes'])} episodes in "
          f"{manifest['wall_time_s']:.0f} s; expert success {manifest['expert_success_rate']:.2f} "
          f"(noise {manifest['noise']})")
    return 0
