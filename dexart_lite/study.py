"""Studies: DexArt's findings re-measured on distilled point-cloud students, arms x seeds, resumable.

    dexart-lite study objects --task laptop --seeds 3 --out runs/studies/laptop_objects
    dexart-lite study encoder --task faucet --seeds 3 --out runs/studies/faucet_encoder
    dexart-lite study imagination --task laptop --arms without --seeds 1 --set rounds=2 --out runs/try

A study compares *arms* (settings of ``DistillConfig``) over seeds. Every arm and seed is one
``dexart-lite distill`` run (expert demonstrations, BC, DAgger rounds, evaluation with deterministic
actions on every seen and unseen object) in ``OUT/<arm>/seed<k>``; a finished one (its ``run.json``
with the same settings) is read back, so an interrupted study resumes where it stopped. All arms of a
study share the evaluation (episodes per object, evaluation seeds) and the data budget: the same
number of expert and DAgger episodes in total, whatever the number of training objects.

Writes ``OUT/study.json`` (arms, per-seed results, mean +- std, command, machine, wall time),
``OUT/study.png`` (success per arm, seen and unseen, every seed as a dot) and ``OUT/study.md`` (a
markdown table). With ``--jobs 2`` two runs go side by side, each with half of the cores' torch threads:
on 2 cores the environment stepping of one (a single thread) overlaps the training of the other.
These are students of a privileged scripted expert (imitation), not PPO: the
studies ask DexArt's questions of the learner that works on a CPU, and say so.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dexart_lite import objects as objects_lib
from dexart_lite.registration import SPECS, TASKS
from dexart_lite.utils import (check_choice, fast_mode, machine_info, parse_overrides, process_pool,
                                sigterm_interrupts, write_json)
from dexart_lite.utils import same_settings as utils_same_settings

RESULT = "run.json"  # in each arm/seed folder: the settings and the results of a finished run


@dataclass(frozen=True)
class Study:
    """One question: its arms (``DistillConfig`` fields each arm sets) and the paper's answer."""

    name: str
    question: str
    paper: str  # DexArt's claim and numbers, for the report
    arms: dict[str, dict]
    viewpoints: bool = False  # also evaluate every student on the camera grid (VIEW_AZIMUTHS x VIEW_POLARS)
    common: dict = dataclasses.field(default_factory=dict)  # fields every arm of the study sets
    pretraining: bool = False  # first pretrain one encoder per method (``prepare_pretrained``)


STUDIES: dict[str, Study] = {
    "objects": Study(
        "objects", "Do more training objects give better success on unseen objects?",
        "DexArt (Sec. 5): policies trained on more objects generalise better to unseen objects",
        {"seen_half": {"split": "seen_half"}, "seen": {"split": "seen"}}),
    "encoder": Study(
        "encoder", "Which PointNet size learns and generalises best?",
        "DexArt (Sec. 5.2): the small PointNet (one hidden layer) is the most sample-efficient and generalises "
        "best; larger encoders do worse",
        {"small": {"encoder": "small"}, "medium": {"encoder": "medium"}, "large": {"encoder": "large"}}),
    "imagination": Study(
        "imagination", "Do the 96 imagined hand points help?",
        "not a DexArt study (DexPoint, Qin et al. 2022, introduced them); DexArt always uses them",
        {"with": {"imagination": True}, "without": {"imagination": False}}),
    "pretrain": Study(
        "pretrain", "Does a pretrained PointNet make a better student, and which pretraining?",
        "DexArt (Table 2): segmentation pretraining on DAM helps most (e.g. Laptop 0.81 / 0.41 without "
        "pretraining -> 0.92 / 0.60 with it, seen / unseen); classification, reconstruction and SimSiam help less",
        {"scratch": {}, **{m: {"pretrained": "{out}/pretrained/" + m + "/encoder.pt"} for m in
                           ("seg", "cls", "recon", "simsiam")}},
        # the points stay raw in every arm (the pretrained PointNets learnt on raw metres); the encoder is
        # fine-tuned, as in DexArt
        common={"normalize_points": False}, pretraining=True),
    "viewpoint": Study(
        "viewpoint", "Does the point-cloud policy keep working when the camera moves?",
        "DexArt (Sec. 5.3, Fig. 9, Laptop): point-cloud policies keep most of their success over 35 camera poses "
        "(azimuth -60..60 deg, polar -20..20 deg) while an image policy collapses away from the training view",
        {"fixed": {"view_range": ""}, "random": {"view_range": "60,20"}}, viewpoints=True),
    "viewpoint-2d": Study(
        "viewpoint-2d", "Does a policy on 2-D depth images keep working when the camera moves?",
        "DexArt (Sec. 5.3, Fig. 9): a policy on images loses its success away from the training view, the "
        "point-cloud policy does not; compare with the `fixed` arm of the viewpoint study",
        # depth_cnn_shift: the same with random shifts of up to 4 px in training (DrQ's augmentation), the
        # usual cure for an image policy that fits its data and fails on the states it visits itself
        {"depth_cnn": {"encoder": "depth_cnn", "view_range": ""},
         "depth_cnn_shift": {"encoder": "depth_cnn", "view_range": "", "image_shift": 4}}, viewpoints=True),
}

# DexArt's robustness grid (``ROBUSTNESS_INIT_CAMERA_CONFIG``): 7 azimuth x 5 polar offsets (degrees) of
# the camera on a sphere of radius 1 m around the point it looks at (``camera.viewpoint``).
VIEW_AZIMUTHS = (-60, -40, -20, 0, 20, 40, 60)
VIEW_POLARS = (-20, -10, 0, 10, 20)
VIEWPOINTS = "viewpoints.json"  # in each arm/seed folder of a viewpoint study


def study_of(name: str) -> Study:
    check_choice("study", name, STUDIES)
    return STUDIES[name]


def arm_config(study: Study, arm: str, task: str, seed: int, out: Path, overrides: dict | None = None):
    """The ``DistillConfig`` of one arm and seed. The study's data budget: an arm that trains on fewer
    objects gets proportionally more episodes per object (rounded), so every arm collects about as many
    expert and student episodes as the full seen split with the defaults."""
    from dexart_lite.imitation.distill import DistillConfig

    check_choice(f"arm of the {study.name} study", arm, study.arms)
    arm_fields = {k: v.format(out=out) if isinstance(v, str) else v for k, v in study.arms[arm].items()}
    fields = {**(overrides or {}), **study.common, **arm_fields}
    cfg = DistillConfig(task=task, seed=seed, out=str(out / arm / f"seed{seed}"), progress=False, **fields)
    if not cfg.objects:
        full = len(objects_lib.list_objects(task, "seen"))
        ours = len(cfg.object_names())
        scale = full / ours
        cfg = dataclasses.replace(cfg, demo_episodes_per_object=max(1, round(cfg.demo_episodes_per_object * scale)),
                                  episodes_per_round=max(1, round(cfg.episodes_per_round * scale)))
    return cfg


def parameters(cfg) -> int:
    """Trainable parameters of the student of ``cfg`` (trunk and both heads)."""
    from dexart_lite.models.actor_critic import make_actor_critic
    from dexart_lite.robot import ACTION_DIM

    net = make_actor_critic(SPECS[cfg.task].state_dim, ACTION_DIM, cfg.encoder, head=tuple(cfg.head_widths()),
                            normalize=cfg.normalize)
    return sum(p.numel() for p in net.parameters())


# PPOConfig / SACConfig fields compared as resolved paths, and fields that say how a run executes or how far it goes
# (not what it learns): not compared, so a run stopped by its time budget, or given more frames, continues
RL_PATH_FIELDS = ("out", "init_from", "pretrained", "bc_demos")
RL_EXECUTION_FIELDS = ("threads", "progress", "device", "resume", "max_minutes", "checkpoint_every", "frames",
                       "trim_memory")


def run_arm(cfg) -> dict:
    """One run of a learner, the one read-back rule of every multi-seed script (studies, ``bench_distill``,
    ``bench_finetune``, ``curriculum_runs``). ``cfg`` is a ``DistillConfig`` (a student), a ``PPOConfig`` or a
    ``SACConfig``. A finished run leaves ``run.json`` in ``cfg.out`` (its settings, success, frames, wall time,
    per-batch history, machine); with the same settings it is read back (``"resumed": True``), with others it is
    an error.

    - Distillation: an interrupted run (a folder without ``run.json``) continues from its last finished round
      (``resume.pt``, ``distill --resume``); one interrupted before its first round ended starts again.
    - PPO and SAC: a run with fewer frames than ``cfg.frames`` (stopped by ``max_minutes``, or asked for more)
      or interrupted (a checkpoint, no ``run.json``) continues from its checkpoint (``--resume``); the record
      says whether it did (``continued``)."""
    from dexart_lite.imitation.distill import DistillConfig

    out = Path(cfg.out)
    record = out / RESULT
    distilled = isinstance(cfg, DistillConfig)
    if distilled and not record.exists():
        _adopt_distillation(out, cfg)
    if distilled and not record.exists() and out.name.startswith("seed"):  # a study's <study>/<arm>/seed<k> folder
        _reuse_identical_run(out, cfg)
    if record.exists():
        done = json.loads(record.read_text())
        if not _same_settings(done["config"], cfg):
            raise _other_settings(out)
        if distilled or done["frames"] >= cfg.frames:
            if not distilled and done["config"]["frames"] > cfg.frames:
                raise ValueError(f"{out} holds a run of {done['frames']} frames, more than the {cfg.frames} asked; "
                                 "ask for its frames or choose another --out")
            return {**done, "resumed": True}
    keep = _distill(cfg, out) if distilled else _reinforce(cfg, out)
    keep["config"] = dataclasses.asdict(cfg)
    keep["machine"] = machine_info()  # wall times compare only within one machine
    write_json(record, keep)
    return {**keep, "resumed": False}


def _adopt_distillation(out: Path, cfg) -> None:
    """A finished ``dexart-lite distill`` run in ``out`` made outside ``run_arm`` (its report, checkpoint and
    evaluations, no ``run.json``) with ``cfg``'s settings gets its ``run.json``, so that it is read back, not
    deleted and trained again; one with other settings is an error."""
    from dexart_lite.imitation.distill import CHECKPOINT
    from dexart_lite.rl.checkpoint import load_checkpoint

    files = [out / name for name in ("report.md", CHECKPOINT, "eval_seen.json", "eval_unseen.json")]
    if not all(f.exists() for f in files):
        return
    payload = load_checkpoint(out / CHECKPOINT)
    if not _same_settings(payload["config"], cfg):
        raise _other_settings(out)
    evals = {split: json.loads((out / f"eval_{split}.json").read_text()) for split in ("seen", "unseen")}
    last = payload["history"][-1]
    write_json(out / RESULT, {**_eval_record(evals),
                              "expert_frames": last["expert_frames"], "student_frames": last["student_frames"],
                              "wall_time_s": last["wall_s"], "history": payload["history"],
                              "config": payload["config"], "machine": None, "adopted": True})


def _other_settings(out: Path) -> ValueError:
    return ValueError(f"{out} holds a run with other settings; delete it or choose another --out")


def _same_settings(recorded: dict, cfg) -> bool:
    from dexart_lite.imitation.distill import DistillConfig, same_settings

    if isinstance(cfg, DistillConfig):
        return same_settings(recorded, cfg)
    return utils_same_settings(recorded, cfg, RL_PATH_FIELDS, RL_EXECUTION_FIELDS)


def _distill(cfg, out: Path) -> dict:
    """A distillation, continued from its last finished round if it was interrupted after one (else from scratch:
    an interrupted one's folder is cleared first); what ``run.json`` keeps."""
    import shutil

    from dexart_lite.imitation.distill import RESUME, distill

    resume = (out / RESUME).is_file()
    if out.exists() and not resume:
        shutil.rmtree(out)
    result = distill(dataclasses.replace(cfg, resume=resume))
    keep = {k: result[k] for k in ("seen_success", "unseen_success", "expert_frames", "student_frames", "wall_time_s")}
    return {**keep, **_eval_record(result["eval"]), "history": result["history"]}


def _reinforce(cfg, out: Path) -> dict:
    """A PPO or SAC run, continued from its checkpoint if it has one; what ``run.json`` keeps. ``wall_time_s`` is
    this invocation's (training and evaluation); the history's ``wall_s`` restarts at each continuation."""
    from dexart_lite.rl.common import CHECKPOINT
    from dexart_lite.rl.learners import learner_of

    continued = (out / CHECKPOINT).exists()
    result = learner_of(cfg).train(dataclasses.replace(cfg, resume=continued))
    return {**_eval_record(result["eval"]), "frames": result["frames"], "wall_time_s": result["wall_time_s"],
            "continued": continued, "demos": result["demos"], "checkpoint": result["checkpoint"],
            "history": result["history"]}


def _eval_record(evals: dict) -> dict:
    """The evaluation's success (``seen_success``, ``unseen_success``), mean stage and per-object success."""
    return {**{f"{split}_success": r["success_rate"] for split, r in evals.items()},
            "mean_max_stage": {split: r["mean_max_stage"] for split, r in evals.items()},
            "per_object": {split: {name: o["success_rate"] for name, o in r["objects"].items()}
                           for split, r in evals.items()}}


def _reuse_identical_run(out: Path, cfg) -> None:
    """Copy into ``out`` a finished run of another study under the same parent folder whose settings are
    ``cfg``'s but for ``out`` (e.g. the objects study's ``seen`` arm is the encoder study's ``small`` arm
    and the imagination study's ``with`` arm): the same seed and settings give the same run, so it is not
    trained twice. The copy's ``run.json`` names the run it came from (``reused_from``)."""
    import shutil

    from dexart_lite.imitation.distill import same_settings

    studies = out.parent.parent.parent  # <parent>/<study>/<arm>/seed<k>
    for record in sorted(studies.glob(f"*/*/{out.name}/{RESULT}")):
        if record.parent.resolve() == out.resolve():
            continue
        done = json.loads(record.read_text())
        if not same_settings({**done["config"], "out": cfg.out}, cfg):
            continue
        if out.exists():  # an interrupted run of its own
            shutil.rmtree(out)
        shutil.copytree(record.parent, out, ignore=shutil.ignore_patterns(VIEWPOINTS))
        done["config"] = dataclasses.asdict(cfg)
        done["reused_from"] = done.get("reused_from", str(record.parent))
        write_json(out / RESULT, done)
        return


# Pretraining for the pretrain study (``prepare_pretrained``): DexArt's recipes with CPU-sized epochs
# (DexArt: seg 100, recon 50, SimSiam 30 epochs over 9,000 clouds per object; cls has no released recipe).
PRETRAIN_EPOCHS = {"seg": 10, "cls": 5, "recon": 10, "simsiam": 10}
PRETRAIN_SAMPLES = 1000  # DAM clouds per object (seen: train + val, unseen: test)
CLASS_WEIGHTS = {"bucket": "3,1,1,1"}  # DexArt's segmentation weights (the bail up-weighted)


def prepare_pretrained(task: str, out: Path, seed: int = 0, progress: bool = True) -> dict:
    """The encoders of the pretrain study in ``out/pretrained/<method>/encoder.pt``: DAM clouds of the
    task (``out/pretrained/dam``: random actions, random joint angles, seen and unseen objects) for seg,
    recon and SimSiam; the objects-only clouds of all four categories (``out/pretrained/objects``) for
    cls. Steps whose output exists are skipped. Returns ``{method: metrics}`` (val = seen objects,
    test = unseen ones), e.g. seg's mIoU."""
    from dexart_lite.pretrain import data as datasets
    from dexart_lite.pretrain import train as pretrain

    root = out / "pretrained"
    fast = fast_mode()
    samples = 20 if fast else PRETRAIN_SAMPLES
    dam, objects = root / "dam", root / "objects"
    if not (dam / "unseen" / datasets.MANIFEST).exists():
        datasets.generate_dam(datasets.DamConfig(task=task, split="all", samples_per_object=samples, out=str(dam),
                                                 seed=seed, progress=progress,
                                                 objects=_first_objects(task) if fast else None))
    if not (objects / "unseen" / datasets.MANIFEST).exists():
        datasets.generate_objects(datasets.ObjectsConfig(samples_per_object=10 if fast else 250, out=str(objects),
                                                         seed=seed, progress=progress,
                                                         objects=_first_objects() if fast else None))
    metrics = {}
    for method, epochs in PRETRAIN_EPOCHS.items():
        run = root / method
        if not (run / "metrics.json").exists():
            pretrain.train(pretrain.PretrainConfig(method=method, data=str(objects if method == "cls" else dam),
                                                   out=str(run), epochs=1 if fast else epochs, seed=seed,
                                                   class_weights=CLASS_WEIGHTS.get(task) if method == "seg" else None,
                                                   progress=progress))
        record = json.loads((run / "metrics.json").read_text())
        metrics[method] = {"data": "objects-only, 4 categories" if method == "cls" else f"DAM, {task}",
                           "epochs": record["epochs"], "train_clouds": record["train_clouds"],
                           "val": record["val"], "test": record.get("test"), "wall_seconds": record["wall_seconds"]}
    return metrics


def _first_objects(task: str | None = None) -> str:
    """Fast mode: one seen and one unseen object of ``task`` (or of every category)."""
    tasks = [task] if task else list(objects_lib.CATEGORIES)
    return ",".join(objects_lib.list_objects(t, s)[0].name for t in tasks for s in ("seen", "unseen"))


def nominal_camera(task: str):
    """The task's training camera (``CameraPose``)."""
    import importlib

    check_choice("task", task, TASKS)
    return getattr(importlib.import_module(f"dexart_lite.envs.{task}"), f"{task.capitalize()}Env").CAMERA


def camera_grid(task: str) -> list[tuple[int, int, object]]:
    """``(d_azimuth, d_polar, CameraPose)`` for the 35 poses of DexArt's grid around the task's camera."""
    from dexart_lite.camera import viewpoint

    base = nominal_camera(task)
    return [(a, p, viewpoint(base, np.deg2rad(a), np.deg2rad(p))) for p in VIEW_POLARS for a in VIEW_AZIMUTHS]


def _evaluate_camera(checkpoint: str, task: str, split: str, episodes: int, seed: int, env_kwargs: dict) -> float:
    """One cell of the viewpoint grid (a worker process's job): the checkpoint's success under one camera."""
    import torch

    from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint
    from dexart_lite.rl.evaluate import evaluate

    torch.set_num_threads(1)
    student = actor_critic_from_checkpoint(load_checkpoint(checkpoint), checkpoint)
    return evaluate(student, task, split, episodes, seed, env_kwargs)["success_rate"]


def evaluate_viewpoints(cfg, episodes_per_object: int = 1, splits=("seen", "unseen"), workers: int | None = None) -> dict:
    """Success of the student in ``cfg.out`` under every camera of ``camera_grid``: ``{split: 5 x 7 list}``
    (rows polar, columns azimuth), deterministic actions, the run's evaluation seed and env settings
    (camera perturbation and point noise included). Each cell seeds its own env, so the cells run in
    ``workers`` processes (default: one per core) with the same result as one after the other. Written
    to ``cfg.out/viewpoints.json``; read back if it exists with the same settings."""
    out = Path(cfg.out)
    path = out / VIEWPOINTS
    settings = {"episodes_per_object": episodes_per_object, "splits": list(splits), "azimuths": list(VIEW_AZIMUTHS),
                "polars": list(VIEW_POLARS), "eval_seed": cfg.eval_seed}
    if path.exists():
        done = json.loads(path.read_text())
        if done["settings"] == settings:
            return done
    start = time.perf_counter()
    cells = [(a, p, split, {**cfg.env_kwargs(), "camera": pose}) for a, p, pose in camera_grid(cfg.task) for split in splits]
    args = [(str(out / "checkpoint.pt"), cfg.task, split, episodes_per_object, cfg.eval_seed, kwargs)
            for _, _, split, kwargs in cells]
    workers = max(1, workers or os.cpu_count() or 1)
    with process_pool(workers) as pool:
        rates = list(pool.map(_evaluate_camera, *zip(*args)))
    grid = {split: np.zeros((len(VIEW_POLARS), len(VIEW_AZIMUTHS))) for split in splits}
    for (a, p, split, _), rate in zip(cells, rates):
        grid[split][VIEW_POLARS.index(p), VIEW_AZIMUTHS.index(a)] = rate
    result = {"settings": settings, "success": {split: g.tolist() for split, g in grid.items()},
              "wall_time_s": round(time.perf_counter() - start, 1), "workers": workers}
    write_json(path, result)
    return result


def _run_job(cfg, viewpoints: bool, workers: int | None = None) -> dict:
    """One arm and seed (``run_arm``), then its viewpoint grid if the study has one; in the main process
    or in a worker process of ``run_study(jobs > 1)``."""
    record = run_arm(cfg)
    if viewpoints:
        record["viewpoints"] = evaluate_viewpoints(cfg, 1, workers=workers)
    return record


def _training_cost(cfg) -> int:
    """A run's training cost, for ordering parallel jobs: its PointNet's multiply-adds per point (0 for
    the depth CNN). Training dominates a run's wall time, and the per-point MLP dominates training."""
    from dexart_lite.models.pointnet import ENCODER_SIZES

    widths = (3, *ENCODER_SIZES.get(cfg.encoder, ()))
    return sum(a * b for a, b in zip(widths, widths[1:]))


def run_study(name: str, task: str, seeds: list[int], out: str | Path, arms: list[str] | None = None,
              overrides: dict | None = None, progress: bool = True, argv: list[str] | None = None,
              jobs: int = 1) -> dict:
    """Run (or resume) every arm x seed of study ``name`` on ``task``; write and return ``study.json``.
    ``jobs`` > 1: that many runs at once in worker processes, each with ``cores // jobs`` torch threads
    (unless ``--set threads=N`` says otherwise)."""
    from concurrent.futures import as_completed

    from tqdm import tqdm

    study = study_of(name)
    check_choice("task", task, TASKS)
    arms = list(study.arms) if arms is None else list(arms)
    for arm in arms:
        check_choice(f"arm of the {name} study", arm, study.arms)
    if not seeds:
        raise ValueError("a study needs at least one seed")
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    overrides = dict(overrides or {})
    if fast_mode():  # a smoke run of the runner itself, not evidence
        overrides.update(num_points=32, max_episode_steps=10, demo_episodes_per_object=1, rounds=1,
                         episodes_per_round=1, epochs=1, epochs_per_round=1, eval_episodes=1, threads=1)
    out = Path(out)
    start = time.perf_counter()
    pretraining = prepare_pretrained(task, out, progress=progress) if study.pretraining else None
    configs = [(arm, seed, arm_config(study, arm, task, seed, out, overrides)) for arm in arms for seed in seeds]
    records: dict[tuple[str, int], dict] = {}
    with sigterm_interrupts(), tqdm(total=len(configs), desc=f"study {name} on {task}", unit="run",
                                     disable=not progress, dynamic_ncols=True) as bar:
        if jobs == 1:
            for arm, seed, cfg in configs:
                bar.set_postfix(arm=arm, seed=seed)
                records[arm, seed] = _run_job(cfg, study.viewpoints)
                bar.update()
        else:
            threads = max(1, (os.cpu_count() or 1) // jobs)
            # the costliest runs first, so that the last one, which runs alone on its share of the cores,
            # is a cheap one (sorted is stable: arms of equal cost keep the study's order)
            queue = sorted(configs, key=lambda c: -_training_cost(c[2]))
            with process_pool(jobs) as pool:  # stopped (error, Ctrl-C, SIGTERM): no worker outlives it
                futures = {pool.submit(_run_job, cfg if cfg.threads else dataclasses.replace(cfg, threads=threads),
                                       study.viewpoints, threads): (arm, seed) for arm, seed, cfg in queue}
                for future in as_completed(futures):
                    records[futures[future]] = future.result()
                    bar.set_postfix(done="{}/seed{}".format(*futures[future]))
                    bar.update()
    runs = {arm: [{"seed": seed, **records[arm, seed]} for seed in seeds] for arm in arms}
    result = summarise(study, task, seeds, runs, out, overrides, time.perf_counter() - start, argv, jobs)
    if pretraining is not None:
        result["pretraining"] = pretraining
    keep_earlier_arms(result, out / "study.json", study)
    write_json(out / "study.json", result)
    plot_study(result, out / "study.png")
    (out / "study.md").write_text(markdown_table(result))
    if study.viewpoints:
        plot_viewpoints(result, out / "viewpoints.png")
    return result


def summarise(study: Study, task: str, seeds: list[int], runs: dict[str, list[dict]], out: Path, overrides: dict,
              wall: float, argv, jobs: int = 1) -> dict:
    # who measured the arms of this invocation (an arm kept from an earlier file keeps its own)
    measured_by = {"command": "dexart-lite study " + " ".join(argv if argv is not None else [study.name, "--task", task]),
                   "machine": machine_info()}
    arms = {}
    for arm, per_seed in runs.items():
        cfg = per_seed[0]["config"]
        entry = {"settings": study.arms[arm], "objects": len(cfg["objects"].split(",")) if cfg["objects"] else
                 len(objects_lib.list_objects(task, cfg["split"])),
                 "demo_episodes_per_object": cfg["demo_episodes_per_object"],
                 "episodes_per_round": cfg["episodes_per_round"], "parameters": parameters(_config(cfg))}
        for key in ("seen_success", "unseen_success"):
            values = [r[key] for r in per_seed]
            entry[key], entry[f"{key}_std"] = float(np.mean(values)), float(np.std(values))
        entry["wall_time_s"] = [round(r["wall_time_s"], 1) for r in per_seed]
        entry["frames"] = [r["expert_frames"] + r["student_frames"] for r in per_seed]
        entry["per_seed"] = [{k: r[k] for k in ("seed", "seen_success", "unseen_success", "expert_frames",
                                                "student_frames", "wall_time_s", "mean_max_stage", "per_object",
                                                "resumed")} |
                            {k: r[k] for k in ("reused_from", "machine") if k in r}
                            for r in per_seed]
        if study.name == "objects":  # the seen split in two: the seen_half objects and the other six
            half = {info.name for info in objects_lib.list_objects(task, "seen_half")}
            for group, keep in (("seen_half_objects", lambda n: n in half), ("other_seen_objects", lambda n: n not in half)):
                values = [float(np.mean([v for n, v in r["per_object"]["seen"].items() if keep(n)])) for r in per_seed]
                entry[f"{group}_success"], entry[f"{group}_success_std"] = float(np.mean(values)), float(np.std(values))
        if "viewpoints" in per_seed[0]:
            entry["viewpoint_success"] = {split: np.mean([r["viewpoints"]["success"][split] for r in per_seed],
                                                         axis=0).round(4).tolist()
                                          for split in per_seed[0]["viewpoints"]["success"]}
            entry["viewpoint_mean"] = {split: float(np.mean(grid)) for split, grid in entry["viewpoint_success"].items()}
            entry["viewpoint_eval_s"] = [r["viewpoints"]["wall_time_s"] for r in per_seed]
        entry["measured_by"] = measured_by
        arms[arm] = entry
    first = next(iter(runs.values()))[0]["config"]
    grid = {"azimuths_deg": list(VIEW_AZIMUTHS), "polars_deg": list(VIEW_POLARS),
            "episodes_per_object": 1} if study.viewpoints else None
    return {"study": study.name, "task": task, "viewpoint_grid": grid, "question": study.question, "paper": study.paper, "seeds": seeds,
            "arms": arms, "eval_episodes_per_object": first["eval_episodes"], "eval_seed": first["eval_seed"],
            "overrides": overrides, "learner": "DAgger students of the scripted expert (imitation, not PPO)",
            "wall_time_s": round(wall, 1),
            "wall_time_note": "this invocation's time; arms read back from an earlier run add none (see per_seed)"
                              + (f"; {jobs} runs at a time, so a run's own wall time counts time it shared the "
                                 "cores" if jobs > 1 else ""),
            "jobs": jobs,
            **measured_by, "fast_mode": fast_mode(), "out": str(out)}


def keep_earlier_arms(result: dict, path: Path, study: Study) -> None:
    """Keep in ``result`` the arms of an earlier ``study.json`` at ``path`` that this invocation did not run.

    A study can be finished arm by arm (``--arms large`` after ``--arms small,medium``), on another day or
    machine, even where the earlier run folders are gone (the committed ``study.json`` copied into ``OUT``).
    Arms are kept only where the two invocations are comparable (same study, task, seeds, evaluation and
    overrides); each kept arm names the ``command`` and the ``machine`` that measured it, and the arms come
    in the study's order. Arms of an incomparable earlier file are not kept (the note says so)."""
    if not path.exists():
        return
    earlier = json.loads(path.read_text())
    same = ("study", "task", "seeds", "eval_episodes_per_object", "eval_seed", "overrides")
    mismatch = [k for k in same if earlier.get(k) != result[k]]
    missing = [arm for arm in earlier.get("arms", {}) if arm not in result["arms"]]
    if not missing:
        return
    if mismatch:
        print(f"note: {path} holds arms {', '.join(missing)} with other {', '.join(mismatch)}; not kept in the new file")
        return
    for arm in missing:
        entry = earlier["arms"][arm]
        entry.setdefault("measured_by", {"command": earlier["command"], "machine": earlier["machine"]})
        result["arms"][arm] = entry
    result["arms"] = {arm: result["arms"][arm] for arm in study.arms if arm in result["arms"]}


def _config(settings: dict):
    from dexart_lite.imitation.distill import DistillConfig

    return DistillConfig(**settings)


def markdown_table(result: dict) -> str:
    """The study as a markdown table: one row per arm, mean +- std over seeds and the seeds' values."""
    lines = [f"# Study `{result['study']}` on {result['task']}", "", result["question"], "",
             f"Paper: {result['paper']}.", "",
             f"Seeds {result['seeds']}; {result['eval_episodes_per_object']} deterministic evaluation episodes per "
             f"object on every seen and unseen object; {result['learner']}.", "",
             "| arm | training objects | seen success | unseen success | per seed (seen / unseen) | parameters | "
             "wall time per seed |", "|---|---|---|---|---|---|---|"]
    for arm, a in result["arms"].items():
        seeds = ", ".join(f"{r['seen_success']:.2f} / {r['unseen_success']:.2f}" for r in a["per_seed"])
        wall = ", ".join(f"{w / 60:.1f}" for w in a["wall_time_s"])
        lines.append(f"| {arm} | {a['objects']} | {a['seen_success']:.2f} ± {a['seen_success_std']:.2f} | "
                     f"{a['unseen_success']:.2f} ± {a['unseen_success_std']:.2f} | {seeds} | {a['parameters']:,} | "
                     f"{wall} min |")
    machines = {arm: a["measured_by"]["machine"]["cpu"] for arm, a in result["arms"].items() if "measured_by" in a}
    if len(set(machines.values())) > 1:
        lines += ["", "Arms measured on different machines (compare wall times only within one): " +
                  "; ".join(f"{arm}: {cpu}" for arm, cpu in machines.items()) + "."]
    if result.get("pretraining"):
        from dexart_lite.pretrain.train import MAIN_METRIC

        lines += ["", "The pretrained encoders (loaded strictly, then fine-tuned in the student):", "",
                  "| method | data | epochs | metric | seen objects (val) | unseen objects (test) |", "|---|---|---|---|---|---|"]
        for method, m in result["pretraining"].items():
            key = MAIN_METRIC[method]
            test = m["test"][key] if m.get("test") and key in m["test"] else float("nan")
            lines.append(f"| {method} | {m['data']} | {m['epochs']} | {key} | {m['val'][key]:.3g} | {test:.3g} |")
    if result["study"] == "objects":
        task = result["task"]
        half, seen = (len(objects_lib.list_objects(task, split)) for split in ("seen_half", "seen"))
        lines += ["", f"The seen split in two (mean ± std over seeds): the {half} `seen_half` {task} objects, on which "
                  f"both arms train, and the other {seen - half} seen ones, on which only `seen` trains:", "",
                  f"| arm | the {half} seen_half objects | the other {seen - half} seen objects |", "|---|---|---|"]
        lines += [f"| {arm} | {a['seen_half_objects_success']:.2f} ± {a['seen_half_objects_success_std']:.2f} | "
                  f"{a['other_seen_objects_success']:.2f} ± {a['other_seen_objects_success_std']:.2f} |"
                  for arm, a in result["arms"].items()]
    views = {arm: a["viewpoint_mean"] for arm, a in result["arms"].items() if "viewpoint_mean" in a}
    if views:
        lines += ["", f"Mean success over the {len(VIEW_AZIMUTHS) * len(VIEW_POLARS)} cameras of DexArt's grid "
                  f"(azimuth {VIEW_AZIMUTHS[0]}..{VIEW_AZIMUTHS[-1]} deg x polar {VIEW_POLARS[0]}..{VIEW_POLARS[-1]} "
                  "deg, 1 episode per object and camera; heatmaps in viewpoints.png):", "",
                  "| arm | seen | unseen |", "|---|---|---|"]
        lines += [f"| {arm} | {v['seen']:.2f} | {v['unseen']:.2f} |" for arm, v in views.items()]
    return "\n".join(lines) + "\n"


def plot_study(result: dict, path: Path) -> Path:
    """Bars: mean success per arm (seen, unseen) with the std over seeds; dots: the seeds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    arms = list(result["arms"])
    x = np.arange(len(arms))
    fig, ax = plt.subplots(figsize=(1.6 + 1.3 * len(arms), 3.4))
    for k, (split, color) in enumerate((("seen", "tab:blue"), ("unseen", "tab:orange"))):
        means = [result["arms"][a][f"{split}_success"] for a in arms]
        stds = [result["arms"][a][f"{split}_success_std"] for a in arms]
        pos = x + (k - 0.5) * 0.36
        ax.bar(pos, means, 0.34, yerr=stds, capsize=3, color=color, alpha=0.75, label=split)
        for p, a in zip(pos, arms):
            values = [r[f"{split}_success"] for r in result["arms"][a]["per_seed"]]
            ax.scatter([p] * len(values), values, color="k", s=10, zorder=3)
    ax.set_xticks(x, arms)
    ax.set(ylim=(0, 1.05), ylabel="success rate",
           title=f"{result['study']} study on {result['task']} ({len(result['seeds'])} seeds)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_viewpoints(result: dict, path: Path) -> Path:
    """One success heatmap per arm and split over the camera grid (mean over seeds)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    arms = list(result["arms"])
    splits = list(result["arms"][arms[0]]["viewpoint_success"])
    fig, axes = plt.subplots(len(arms), len(splits), figsize=(3.6 * len(splits), 2.6 * len(arms)), squeeze=False)
    for i, arm in enumerate(arms):
        for j, split in enumerate(splits):
            grid = np.array(result["arms"][arm]["viewpoint_success"][split])
            ax = axes[i][j]
            im = ax.imshow(grid, vmin=0, vmax=1, cmap="viridis", origin="upper")
            for (r, c), v in np.ndenumerate(grid):
                ax.text(c, r, f"{v:.2f}", ha="center", va="center", fontsize=6, color="w" if v < 0.6 else "k")
            ax.set_xticks(range(len(VIEW_AZIMUTHS)), VIEW_AZIMUTHS, fontsize=7)
            ax.set_yticks(range(len(VIEW_POLARS)), VIEW_POLARS, fontsize=7)
            ax.set(xlabel="azimuth offset (deg)", ylabel="polar offset (deg)",
                   title=f"{arm} camera in training, {split}")
            ax.title.set_fontsize(8)
    fig.colorbar(im, ax=axes.ravel().tolist(), shrink=0.8, label="success")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


# ----------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("study", help=f"one of {', '.join(STUDIES)}")
    parser.add_argument("--task", default="laptop", help=f"one of {', '.join(TASKS)}")
    parser.add_argument("--seeds", type=int, default=3, help="number of seeds (0, 1, ..., N-1)")
    parser.add_argument("--arms", default=None, help="comma-separated arms (default: all of the study)")
    parser.add_argument("--set", dest="overrides", nargs="+", default=[], metavar="FIELD=VALUE",
                        help="DistillConfig fields every arm shares, e.g. rounds=4 (the arms' own fields win)")
    parser.add_argument("--out", type=Path, default=None, help="study folder (default runs/studies/<task>_<study>)")
    parser.add_argument("--jobs", type=int, default=1, help="runs at a time, each with cores/jobs torch threads "
                        "(2 on 2 cores: one run's single-threaded simulation overlaps the other's training)")
    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=True, help="show a progress bar")


def run(args: argparse.Namespace) -> int:
    from dexart_lite.imitation.distill import DistillConfig

    study = study_of(args.study)
    if args.seeds < 1:
        raise ValueError(f"--seeds must be >= 1, got {args.seeds}")
    arms = [a.strip() for a in args.arms.split(",") if a.strip()] if args.arms else None
    out = args.out or Path("runs/studies") / f"{args.task}_{study.name}"
    argv = [study.name, "--task", args.task, "--seeds", str(args.seeds), "--out", str(out)] + \
        (["--arms", args.arms] if args.arms else []) + (["--set", *args.overrides] if args.overrides else []) + \
        (["--jobs", str(args.jobs)] if args.jobs != 1 else [])
    result = run_study(study.name, args.task, list(range(args.seeds)), out, arms,
                       parse_overrides(args.overrides, DistillConfig), args.progress, argv, args.jobs)
    print(markdown_table(result))
    print(f"wrote {out / 'study.json'}, {out / 'study.png'}, {out / 'study.md'}")
    return 0
