"""Distil the scripted expert into a point-cloud student: behaviour cloning, then optionally DAgger.

    dexart-lite distill --task laptop --method bc --epochs 30 --out runs/bc_laptop
    dexart-lite distill --task laptop --method dagger --rounds 3 --episodes-per-round 4 --out runs/dagger_laptop
    dexart-lite eval --ckpt runs/dagger_laptop/checkpoint.pt --split unseen

The student is the PPO actor-critic (``models.actor_critic.make_actor_critic``: PointNet trunk +
policy head); it sees only what a PPO policy sees (the 608-point cloud and the state vector), while
the expert reads the simulator. ``distill`` reads top to bottom:

1. demonstrations: ``demos.collect_demos`` (expert with executed-action noise, clean labels), or an
   existing folder (``--demos``);
2. behaviour cloning: the policy head's mean (``loc``) regressed onto the expert labels
   (``train_student``, MSE or the Gaussian NLL with the state-independent scale);
3. DAgger (``--method dagger``), ``rounds`` times: run ``episodes_per_round`` episodes per object
   in which each step executes the expert's action with probability beta, else the student's
   deterministic action; the expert labels EVERY visited state; the samples join the aggregate
   buffer (at most ``max_samples``, oldest dropped) and the student trains on all of it, from its
   current weights. beta is multiplied by ``beta_decay`` after each round (never below ``beta_min``);
   with ``drop_failed`` only the round's successful episodes join the buffer;
4. ``checkpoint.pt`` (the PPO checkpoint format, so ``dexart-lite eval`` loads it), ``encoder.pt``
   (for ``dexart-lite train --pretrained``), ``log.csv``, evaluation on seen and unseen objects
   (``eval_seen.json``, ``eval_unseen.json``), ``rounds.png`` and ``report.md`` (``imitation/report.py``).

After every round the run keeps what it needs to continue (``resume.pt``: the student, its EMA and auxiliary
head, the log; ``rounds/<r>``: that round's samples; the demonstrations are in ``demos``), so an interrupted run
continues from its last finished round with ``--resume`` and ends as the uninterrupted one would (every round's
episodes and every training pass draw from generators seeded by the run's seed and the round). Both are deleted
once the run has written its report (a run stopped in its evaluation resumes after its last round).
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDictBase
from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import ActorValueOperator
from tqdm import tqdm

from dexart_lite import objects as objects_lib
from dexart_lite.demos import Recorder, collect_demos, episode_list, load_demos, read_manifest
from dexart_lite.imitation.report import plot_rounds, write_report
from dexart_lite.models.actor_critic import (ENCODERS, HIDDEN_KEY, IMAGE_KEY, POINTS_KEY, STATE_KEY, architecture,
                                             encoder_label, encoder_of, input_key, make_actor_critic, trunk_of)
from dexart_lite.models.pointnet import load_encoder, save_encoder
from dexart_lite.registration import SPECS, TASKS, state_slices
from dexart_lite.rl.checkpoint import policy_function, save_checkpoint
from dexart_lite.rl.env import torch_threads
from dexart_lite.rl.evaluate import evaluate_splits, record_gif
from dexart_lite.rollout import Policy, per_object_summary, run_episodes
from dexart_lite.utils import DEVICES, check_choice, resolve_device, write_json
from dexart_lite.utils import changed_settings, same_settings as _same_settings

METHODS = ("bc", "dagger")
LOSSES = ("mse", "l1", "nll")
CHECKPOINT = "checkpoint.pt"
RESUME = "resume.pt"  # the state of an unfinished run after its last round (deleted when the run finishes)
ROUNDS = "rounds"  # rounds/<r>: the samples DAgger round r added to the buffer (memory-mapped; deleted with it)


# State entries a task's students do not see by default (drop_state="auto"). The palm velocity is nearly
# the last action (velocity control): a laptop student that sees it learns to repeat itself and stalls
# where it once stopped (the "copycat" problem of behaviour cloning); masking it and the time raised
# laptop students from 0.29 / 0.37 to 0.56 / 0.43 (seen / unseen, 3 seeds each). On faucets the same
# mask cut them from 0.58 / 0.40 to 0.28 / 0.25 (3 seeds; turning a handle may need its speed), so
# the other tasks keep the full state (toilet and bucket are not measured).
# Evidence: benchmarks/results/students/distill_{laptop,laptop_novel,faucet,faucet_novel}.json.
DROP_STATE = {t: spec.student_drops for t, spec in SPECS.items() if spec.student_drops}  # registration.SPECS


@dataclass
class DistillConfig:
    """One distillation run. On Laptop (11 seen objects, 250-step episodes) the defaults collect about
    11k expert frames and 16.5k student frames, and evaluate on 85 episodes."""

    task: str = field(default="laptop", metadata={"help": f"one of {', '.join(TASKS)}"})
    method: str = field(default="dagger", metadata={"help": "bc (demonstrations only) or dagger"})
    encoder: str = field(default="small", metadata={"help": "PointNet size: small, medium, large; or depth_cnn, the "
                         "2-D baseline (a CNN on the 64x64 depth image of the same camera instead of the cloud)"})
    split: str = field(default="seen", metadata={"help": "training objects: seen, seen_half or seen_wide (seen + "
                       "the wide split's extra toilets)"})
    objects: str | None = field(default=None, metadata={"help": "comma-separated training objects (default: the split)"})
    demos: str | None = field(default=None, metadata={"help": "start from this `dexart-lite data demos` folder"})
    demo_episodes_per_object: int = field(default=4, metadata={"help": "expert episodes per object for BC"})
    demo_noise: float = field(default=0.15, metadata={"help": "std of the noise on the expert's executed actions"})
    rounds: int = field(default=6, metadata={"help": "DAgger rounds after BC"})
    episodes_per_round: int = field(default=2, metadata={"help": "DAgger episodes per object and round"})
    epochs: int = field(default=40, metadata={"help": "BC epochs over the demonstrations"})
    epochs_per_round: int = field(default=6, metadata={"help": "epochs over the aggregate buffer after each round"})
    beta: float = field(default=0.5, metadata={"help": "DAgger: probability of executing the expert's action, round 1"})
    beta_decay: float = field(default=0.6, metadata={"help": "DAgger: beta is multiplied by this after each round"})
    beta_min: float = field(default=0.0, metadata={"help": "DAgger: beta never falls below this (the expert keeps "
                            "driving about this share of the steps in every round); 0: plain decay"})
    drop_failed: bool = field(default=False, metadata={"help": "DAgger: the buffer keeps only the samples of the "
                              "round's successful episodes (the failed ones' states and labels are dropped)"})
    student_noise: float = field(default=0.0, metadata={"help": "DAgger: std of Gaussian noise on the student's "
                                 "executed actions (its labels stay the expert's clean actions); 0: none"})
    lr: float = field(default=1e-3, metadata={"help": "Adam learning rate"})
    ema: float = field(default=0.995, metadata={"help": "decay of the exponential moving average of the weights "
                       "that acts and is saved (0: the trained weights themselves)"})
    batch_size: int = 256
    weight_decay: float = field(default=0.0, metadata={"help": "Adam weight decay"})
    loss: str = field(default="mse", metadata={"help": "mse on the mean action; l1 (its median: where the expert's "
                      "labels for one observation split between two actions, the mean of both may be neither); or "
                      "nll (Gaussian, trains the log-std)"})
    aux_coef: float = field(default=1.0, metadata={"help": "weight of the auxiliary loss: the trunk's features also "
                            "predict the expert's privileged object state (a linear head, dropped after training; "
                            "0: off)"})
    init_log_std: float = field(default=0.0, metadata={"help": "initial log std of the student's actions (for PPO)"})
    head: str = field(default="256,256", metadata={"help": "hidden widths of the policy and value MLPs (DexArt: 64,64)"})
    normalize: bool = field(default=True, metadata={"help": "fixed input normalisation in the trunk, set from the "
                            "demonstrations (DexArt: none)"})
    normalize_points: bool = field(default=True, metadata={"help": "with --normalize, also centre and scale the "
                                   "points (off: raw metres, as a pretrained PointNet saw them)"})
    pretrained: str | None = field(default=None, metadata={"help": "encoder file (`dexart-lite pretrain`'s "
                                   "encoder.pt) loaded strictly into the student's PointNet before BC"})
    drop_state: str = field(default="auto", metadata={"help": "state entries the student does not see (needs "
                            "--normalize; '' for none; auto: DROP_STATE of the task): comma-separated from time, "
                            "palm_velocity"})
    arm_weight: float = field(default=3.0, metadata={"help": "loss weight of the 6 arm (twist) dimensions relative "
                              "to the 16 hand dimensions"})
    max_samples: int = field(default=200_000, metadata={"help": "aggregate buffer size; the oldest samples go first"})
    num_points: int = field(default=512, metadata={"help": "observed points per cloud (+96 imagined)"})
    imagination: bool = field(default=True, metadata={"help": "append the 96 imagined hand points to the cloud "
                              "(DexArt: on)"})
    view_range: str = field(default="", metadata={"help": "random camera viewpoints in collection: azimuth,polar "
                            "half-widths in degrees on DexArt's viewpoint sphere, e.g. 60,20 ('': DexArt's fixed "
                            "camera); evaluation always uses the fixed camera"})
    image_shift: int = field(default=0, metadata={"help": "depth_cnn only: random shifts of the depth image by up "
                             "to this many pixels in training (edge pixels repeated; DrQ, Kostrikov et al. 2021); "
                             "0: none"})
    point_erase: float = field(default=0.0, metadata={"help": "probability that a training sample loses its observed "
                               "points within a ball around one of them, drawn at random (an occlusion; the gap is "
                               "filled with copies of its other observed points, the imagined hand points stay); "
                               "0: off"})
    point_erase_radius: float = field(default=0.15, metadata={"help": "with --point-erase, the largest radius of the "
                                      "ball, m; each draw is U[0.25, 1] x this"})
    camera_noise: bool = field(default=True, metadata={"help": "DexArt's per-reset camera perturbation (1.5 cm, "
                               "0.05 rad std) in collection and evaluation"})
    max_episode_steps: int | None = field(default=None, metadata={"help": "episode length (None: the task's 250)"})
    seed: int = 0
    eval_episodes: int = field(default=3, metadata={"help": "evaluation episodes per object and split (0: none)"})
    eval_seed: int = 100
    out: str = field(default="runs/distill", metadata={"help": "output folder"})
    gif: bool = field(default=False, metadata={"help": "save a GIF of one evaluation episode on an unseen object"})
    threads: int = field(default=0, metadata={"help": "torch threads for training (0: all cores)"})
    device: str = field(default="cpu", metadata={"help": "where the student trains: cpu, cuda or auto (cuda where "
                        "there is one); it acts (DAgger, evaluation) on the CPU"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    max_minutes: float | None = field(default=None, metadata={"help": "time budget: no new DAgger round after it"})
    resume: bool = field(default=False, metadata={"help": "continue an interrupted run in --out from its last "
                         "finished round"})

    def env_kwargs(self) -> dict:
        """Keyword arguments of the env shared by collection, evaluation and the GIF."""
        kwargs = {"num_points": self.num_points, "point_noise": True, "camera_noise": self.camera_noise,
                  "imagination": self.imagination}
        if self.encoder == "depth_cnn":  # the 2-D baseline reads the camera's depth image
            kwargs["depth_image"] = True
        if self.max_episode_steps:
            kwargs["max_episode_steps"] = self.max_episode_steps
        return kwargs

    def view_range_degrees(self) -> tuple[float, float] | None:
        """``view_range`` as (azimuth, polar) degrees, or None for the fixed camera."""
        if not self.view_range.strip():
            return None
        try:
            values = tuple(float(v) for v in self.view_range.split(","))
        except ValueError:
            values = ()
        if len(values) != 2 or not all(math.isfinite(v) and v >= 0 for v in values):
            raise ValueError(f"view_range must be two degrees >= 0 such as 60,20 (azimuth, polar); got {self.view_range!r}")
        return values

    def dropped_state(self, state_dim: int) -> list[int]:
        """Indices of ``drop_state`` in the env's state vector (registration.STATE_LAYOUT) of ``state_dim`` entries."""
        slices = state_slices(self.task)
        if slices["time"].stop != state_dim:
            raise ValueError(f"a {self.task} state vector has {slices['time'].stop} entries, not {state_dim}")
        where = {name: list(range(state_dim))[slices[name]] for name in ("time", "palm_velocity")}
        drop = DROP_STATE.get(self.task, "") if self.drop_state == "auto" else self.drop_state
        names = [n.strip() for n in drop.split(",") if n.strip()]
        for name in names:
            check_choice("dropped state entry", name, where)
        if names and not self.normalize:
            raise ValueError("drop_state needs normalize (the mask lives in the input normalisation); "
                             "with --no-normalize pass --drop-state ''")
        return [i for name in names for i in where[name]]

    def head_widths(self) -> list[int]:
        try:
            widths = [int(w) for w in self.head.split(",") if w.strip()]
        except ValueError:
            widths = []
        if not widths or min(widths) < 1:
            raise ValueError(f"head must be comma-separated positive widths such as 64,64; got {self.head!r}")
        return widths

    def object_names(self) -> list[str]:
        in_split = [info.name for info in objects_lib.list_objects(self.task, self.split)]
        if not self.objects:
            return in_split
        names = [n.strip() for n in self.objects.split(",") if n.strip()]
        for name in names:
            check_choice(f"{self.split} {self.task} object", name, in_split)
        return names


PATH_FIELDS = ("out", "demos", "pretrained")  # compared as resolved paths: runs/x and /abs/runs/x are one folder
EXECUTION_FIELDS = ("threads", "progress", "device", "resume")  # how a run executes, not what it learns: not compared


def same_settings(recorded: dict, cfg: DistillConfig) -> bool:
    """Whether a finished run's recorded config is ``cfg`` (``utils.same_settings``): ``PATH_FIELDS`` compared
    resolved, ``EXECUTION_FIELDS`` not compared, so a study run with ``--jobs 2`` (one thread per run) reads
    back the runs of one with ``--jobs 1``."""
    return _same_settings(recorded, cfg, PATH_FIELDS, EXECUTION_FIELDS)


def validate(cfg: DistillConfig) -> None:
    """``ValueError`` naming the valid choices or range for the first bad field."""
    check_choice("task", cfg.task, TASKS)
    check_choice("method", cfg.method, METHODS)
    check_choice("device", cfg.device, DEVICES)
    if cfg.device == "cuda":
        resolve_device(cfg.device)  # no CUDA here: one line, before any demonstration is collected
    check_choice("encoder", cfg.encoder, ENCODERS)
    check_choice("training split", cfg.split, objects_lib.TRAINING_SPLITS)
    check_choice("loss", cfg.loss, LOSSES)
    for name in ("demo_episodes_per_object", "rounds", "episodes_per_round", "epochs", "epochs_per_round",
                 "batch_size", "max_samples", "num_points"):
        if getattr(cfg, name) < 1:
            raise ValueError(f"{name} must be >= 1, got {getattr(cfg, name)}")
    if not 0.0 <= cfg.ema < 1.0:
        raise ValueError(f"ema must be in [0, 1), got {cfg.ema}")
    if not (math.isfinite(cfg.student_noise) and cfg.student_noise >= 0):
        raise ValueError(f"student_noise must be a finite std >= 0, got {cfg.student_noise}")
    for name in ("beta", "beta_decay", "beta_min"):
        if not 0.0 <= getattr(cfg, name) <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {getattr(cfg, name)}")
    if not (math.isfinite(cfg.demo_noise) and cfg.demo_noise >= 0):
        raise ValueError(f"demo_noise must be a finite std >= 0, got {cfg.demo_noise}")
    if not (math.isfinite(cfg.aux_coef) and cfg.aux_coef >= 0):
        raise ValueError(f"aux_coef must be a finite weight >= 0, got {cfg.aux_coef}")
    if not (cfg.lr > 0 and cfg.weight_decay >= 0 and math.isfinite(cfg.init_log_std)):
        raise ValueError(f"need lr > 0, weight_decay >= 0 and a finite init_log_std, got {cfg.lr}, "
                         f"{cfg.weight_decay}, {cfg.init_log_std}")
    if cfg.eval_episodes < 0 or cfg.threads < 0:
        raise ValueError(f"eval_episodes and threads must be >= 0, got {cfg.eval_episodes}, {cfg.threads}")
    if cfg.max_minutes is not None and not cfg.max_minutes > 0:
        raise ValueError(f"max_minutes must be > 0, got {cfg.max_minutes}")
    cfg.head_widths()
    cfg.view_range_degrees()
    cfg.dropped_state(SPECS[cfg.task].state_dim)
    if not (math.isfinite(cfg.arm_weight) and cfg.arm_weight > 0):
        raise ValueError(f"arm_weight must be a finite weight > 0, got {cfg.arm_weight}")
    if not 0 <= cfg.image_shift <= 16:
        raise ValueError(f"image_shift must be 0 to 16 pixels, got {cfg.image_shift}")
    if cfg.image_shift and cfg.encoder != "depth_cnn":
        raise ValueError("image_shift shifts the depth image of the depth_cnn student; "
                         "this student reads the point cloud")
    if not 0.0 <= cfg.point_erase <= 1.0:
        raise ValueError(f"point_erase must be a probability in [0, 1], got {cfg.point_erase}")
    if not (math.isfinite(cfg.point_erase_radius) and cfg.point_erase_radius > 0):
        raise ValueError(f"point_erase_radius must be a finite radius > 0 (m), got {cfg.point_erase_radius}")
    if cfg.point_erase and cfg.encoder == "depth_cnn":
        raise ValueError("point_erase erases points of the cloud; the depth_cnn student reads the depth image")
    if cfg.pretrained and cfg.encoder == "depth_cnn":
        raise ValueError("--pretrained holds a PointNet; the depth_cnn student has no PointNet to load it into")
    if cfg.pretrained and not Path(cfg.pretrained).is_file():
        raise FileNotFoundError(f"pretrained encoder not found: {cfg.pretrained}")
    cfg.object_names()


# ----------------------------------------------------------------------------- learning
def build_student(cfg: DistillConfig, dims: dict, demos: TensorDictBase
                  ) -> tuple[ActorValueOperator, AveragedModel | None, torch.nn.Module]:
    """The untrained student of ``cfg``: ``(actor_critic, ema, aux_head)``. ``dims``: ``state_dim``,
    ``action_dim`` and the architecture fields of a checkpoint (``rl.checkpoint.architecture``);
    ``demos``: the demonstrations, which set the fixed input normalisation."""
    actor_critic = make_actor_critic(dims["state_dim"], dims["action_dim"], cfg.encoder, cfg.init_log_std,
                                     **architecture(dims))
    if cfg.normalize:  # from the demonstrations, once: the student's inputs keep one meaning
        use_points = cfg.normalize_points and cfg.encoder != "depth_cnn"
        trunk_of(actor_critic).set_normalization(demos[STATE_KEY], demos[POINTS_KEY] if use_points else None,
                                                 cfg.dropped_state(dims["state_dim"]))
    if cfg.pretrained:  # strict: a size or key mismatch is an error
        load_encoder(cfg.pretrained, encoder_of(actor_critic), strict=True)
    # The student that acts and is saved: an exponential moving average of the trained weights (a
    # closed-loop policy is sensitive to the last few gradient steps; the average is steadier).
    ema = AveragedModel(actor_critic, multi_avg_fn=get_ema_multi_avg_fn(cfg.ema), use_buffers=True) \
        if cfg.ema > 0 else None
    # the auxiliary head (trunk features -> privileged object state) lives only during distillation
    aux_head = torch.nn.Linear(actor_critic.module[0].module.out_dim, demos["privileged"].shape[-1])
    return actor_critic, ema, aux_head


def erase_ball(points: torch.Tensor, imagined: torch.Tensor, prob: float, max_radius: float,
               generator: torch.Generator) -> torch.Tensor:
    """A random occlusion of point clouds (B, N, 3), m: each cloud, with probability ``prob``, loses the observed
    points (``imagined`` (B, N) False) within a ball of radius U[0.25, 1] x ``max_radius`` around one of them drawn
    at random, and each lost point is replaced by a copy of one of its kept observed points, drawn at random (so N
    stays, and a max-pooling PointNet sees the cloud without the ball). The imagined hand points never change; a
    cloud the ball would empty is left as it is. Returns a new tensor."""
    b, n, _ = points.shape
    observed = ~imagined
    centre_idx = torch.multinomial(observed.float() + 1e-12, 1, generator=generator)  # (B, 1) an observed point
    centre = points.gather(1, centre_idx[..., None].expand(-1, -1, 3))  # (B, 1, 3)
    radius = max_radius * (0.25 + 0.75 * torch.rand(b, 1, generator=generator))
    chosen = torch.rand(b, 1, generator=generator) < prob
    lost = chosen & observed & ((points - centre).norm(dim=-1) < radius)  # (B, N)
    kept = observed & ~lost
    lost &= kept.any(dim=1, keepdim=True)  # a ball that covers every observed point: no erasure
    source = torch.multinomial(kept.float() + 1e-12, n, replacement=True, generator=generator)  # (B, N) kept points
    fill = points.gather(1, source[..., None].expand(-1, -1, 3))
    return torch.where(lost[..., None], fill, points)


def random_shift(images: torch.Tensor, pad: int, generator: torch.Generator) -> torch.Tensor:
    """Each (H, W) image of ``images`` (B, H, W) moved by its own random offset of -pad..pad pixels in
    each direction, the edge pixels repeated into the gap (DrQ's augmentation for image policies)."""
    b, h, w = images.shape
    padded = torch.nn.functional.pad(images[:, None], (pad, pad, pad, pad), mode="replicate")[:, 0]
    dy, dx = (torch.randint(0, 2 * pad + 1, (b,), generator=generator) for _ in range(2))
    rows = (dy[:, None] + torch.arange(h))[:, :, None]  # (B, H, 1)
    cols = (dx[:, None] + torch.arange(w))[:, None, :]  # (B, 1, W)
    return padded[torch.arange(b)[:, None, None], rows, cols]


def train_student(actor_critic: ActorValueOperator, data: TensorDictBase, cfg: DistillConfig,
                  epochs: int, aux_head: torch.nn.Module | None = None, ema: AveragedModel | None = None,
                  device: torch.device | None = None) -> list[float]:
    """Regress the policy mean onto ``data["expert_action"]`` for ``epochs`` shuffled passes (Adam,
    minibatches of ``cfg.batch_size``); returns the mean loss of each epoch. ``data``: a TensorDict
    of samples (``demos.SAMPLE_SPECS``), in memory or memory-mapped. ``ema``: an exponential moving
    average of the weights, updated after every step.

    With ``aux_head`` (a Linear from the trunk's 320 features to ``data["privileged"]``'s size) and
    ``cfg.aux_coef > 0``, the loss adds ``aux_coef`` times the MSE of the head's prediction of the
    privileged object state (standardised over ``data``): the point-cloud encoder is made to carry
    the lid's pose and shape, which the action regression alone teaches it too slowly (a student given
    that state directly, as numbers, imitates the laptop expert; one given only the cloud did not).

    ``device`` (not the CPU): the networks train there, fed minibatches moved there, and come back to the
    CPU at the end, where they act."""
    if device is None or device.type == "cpu":
        return fit_student(actor_critic, data, cfg, epochs, aux_head, ema)
    modules = [m for m in (actor_critic, aux_head, ema) if m is not None]
    try:
        for module in modules:
            module.to(device)
        return fit_student(actor_critic, data, cfg, epochs, aux_head, ema, device)
    finally:
        for module in modules:
            module.cpu()


def fit_student(actor_critic: ActorValueOperator, data: TensorDictBase, cfg: DistillConfig, epochs: int,
                aux_head: torch.nn.Module | None, ema: AveragedModel | None,
                device: torch.device | None = None) -> list[float]:
    """``train_student``'s passes, with the networks already on ``device`` (None: the CPU, as stored)."""
    policy = actor_critic.get_policy_operator()  # trunk + policy head; the value head is not trained
    use_aux = aux_head is not None and cfg.aux_coef > 0
    params = list(policy.parameters()) + (list(aux_head.parameters()) if use_aux else [])
    optimizer = torch.optim.Adam(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
    if use_aux:
        privileged = data["privileged"]
        mean, std = privileged.mean(0), privileged.std(0).clamp_min(1e-3)  # constant entries: no signal, no blow-up
        mean, std = (mean.to(device), std.to(device)) if device is not None else (mean, std)
    generator = torch.Generator().manual_seed(cfg.seed)
    n = data.batch_size[0]
    weights = torch.ones(data["expert_action"].shape[-1])  # per action dimension, mean 1
    weights[:6] = cfg.arm_weight
    weights *= len(weights) / weights.sum()
    weights = weights.to(device) if device is not None else weights
    losses = []
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(epochs):
            total = 0.0
            for idx in torch.randperm(n, generator=generator).split(cfg.batch_size):
                batch = data[idx]  # a copy: the shift below leaves the data as they are
                if cfg.image_shift:
                    batch[IMAGE_KEY] = random_shift(batch[IMAGE_KEY], cfg.image_shift, generator)
                if cfg.point_erase:
                    batch[POINTS_KEY] = erase_ball(batch[POINTS_KEY], batch["imagined_mask"].bool(), cfg.point_erase,
                                                   cfg.point_erase_radius, generator)
                batch = batch.to(device) if device is not None else batch  # after the shift: its draws are on the CPU
                out = policy(batch.select(input_key(cfg.encoder), STATE_KEY))
                target = batch["expert_action"]  # (B, 22)
                if cfg.loss == "mse":
                    loss = ((out["loc"] - target).pow(2) * weights).mean()
                elif cfg.loss == "l1":  # the conditional median (ACT, Zhao et al. 2023, chose L1 for precise actions)
                    loss = ((out["loc"] - target).abs() * weights).mean()
                else:  # Gaussian NLL per action, with the state-independent scale
                    loss = -torch.distributions.Normal(out["loc"], out["scale"]).log_prob(target).sum(-1).mean()
                if use_aux:
                    goal = (batch["privileged"] - mean) / std
                    loss = loss + cfg.aux_coef * (aux_head(out[HIDDEN_KEY]) - goal).pow(2).mean()
                optimizer.zero_grad()
                loss.backward()
                optimizer.step()
                if ema is not None:
                    ema.update_parameters(actor_critic)
                total += float(loss.detach()) * len(idx)
            losses.append(total / n)
    return losses


class Mixture:
    """DAgger's executed policy: the expert labels every step (``label``); its action is executed with
    probability ``beta``, the student's otherwise. ``rng``: a ``numpy.random.Generator``."""

    def __init__(self, expert: Policy, student: Policy, beta: float, rng: np.random.Generator, noise: float = 0.0):
        self.expert, self.student, self.beta, self.rng, self.noise = expert, student, beta, rng, noise
        self.label: np.ndarray | None = None
        self.privileged: np.ndarray | None = None
        self.expert_steps = self.steps = 0

    def reset(self) -> None:
        for policy in (self.expert, self.student):
            if hasattr(policy, "reset"):
                policy.reset()

    def __call__(self, obs: dict) -> np.ndarray:
        self.label = np.asarray(self.expert(obs), dtype=np.float32)  # every step: the expert follows the episode
        self.privileged = getattr(self.expert, "privileged", None)
        self.steps += 1
        if self.rng.random() < self.beta:
            self.expert_steps += 1
            return np.clip(self.label, -1.0, 1.0)
        action = np.asarray(self.student(obs), dtype=np.float32)
        if self.noise > 0:  # off the student's own path, so the expert also labels how to get back onto it
            action = action + self.noise * self.rng.standard_normal(action.shape).astype(np.float32)
        return np.clip(action, -1.0, 1.0)


def dagger_beta(cfg: DistillConfig, r: int) -> float:
    """The probability that the expert's action is executed in DAgger round ``r`` (1, 2, ...): ``beta`` decayed by
    ``beta_decay`` per round, never below ``beta_min``."""
    return max(cfg.beta_min, cfg.beta * cfg.beta_decay ** (r - 1))


def successful_episodes(samples: TensorDictBase) -> TensorDictBase:
    """The samples of the episodes that succeeded at some step (``samples["success"]`` is the success after each
    step, ``samples["episode"]`` the episode's index)."""
    episode = samples["episode"]
    return samples[torch.isin(episode, episode[samples["success"].bool()])]


def collect_dagger(env, expert: Policy, student: Policy, episodes: list[tuple[int, str]], beta: float,
                   rng: np.random.Generator, objects: list[str], first_episode: int = 0, student_noise: float = 0.0):
    """One DAgger round: ``(samples, episode results, share of steps the expert drove)``."""
    mixture = Mixture(expert, student, beta, rng, student_noise)
    recorder = Recorder(mixture, objects, first_episode)
    with torch.no_grad(), torch_threads(1):  # acting one step at a time: fastest on one thread
        results = run_episodes(mixture, env, episodes, on_step=recorder)
    return recorder.samples(), results, mixture.expert_steps / max(mixture.steps, 1)


# ----------------------------------------------------------------------------- the run
class StudentRun:
    """One distillation's moving parts: the DAgger env, the student (and its EMA and auxiliary head), the
    aggregate buffer, the per-round log and the progress bar; ``distill`` calls its steps in order."""

    def __init__(self, cfg: DistillConfig, out: Path, start: float, device, demos: TensorDictBase, manifest: dict):
        from torchrl.data import LazyMemmapStorage, ReplayBuffer

        from dexart_lite.envs import make

        self.cfg, self.out, self.start, self.device, self.manifest = cfg, out, start, device, manifest
        self.names = cfg.object_names()
        self.budget = 60 * cfg.max_minutes if cfg.max_minutes else None
        # collection (DAgger) env: evaluation's settings, plus random viewpoints if asked for
        self.env = make(cfg.task, split=cfg.split, object_names=self.names, view_range=cfg.view_range_degrees(),
                        **cfg.env_kwargs())
        space = self.env.observation_space
        self.dims = {"num_points": space["point_cloud"].shape[0], "state_dim": space["state"].shape[0],
                     "action_dim": self.env.action_space.shape[0], "head": cfg.head_widths(), "normalize": cfg.normalize}
        self.actor_critic, self.ema, self.aux_head = build_student(cfg, self.dims, demos)
        self.student_net = self.ema.module if self.ema is not None else self.actor_critic
        # the buffer is scratch space, refilled from the demonstrations and rounds on a resume: a run killed outright
        # (SIGKILL, a pool worker terminated, the machine gone) leaves its files behind, which the storage refuses
        shutil.rmtree(out / "buffer", ignore_errors=True)
        self.buffer = ReplayBuffer(storage=LazyMemmapStorage(cfg.max_samples, scratch_dir=str(out / "buffer")))
        self.history: list[dict] = []
        self.frames = {"expert": manifest["samples"], "student": 0}
        self.rounds = cfg.rounds if cfg.method == "dagger" else 0
        # with a time budget the bar counts seconds of it, so its ETA is the budget's end
        budget = self.budget
        self.bar = tqdm(total=round(budget) if budget else 1 + self.rounds, unit="s" if budget else "round",
                        initial=min(round(time.perf_counter() - start), round(budget)) if budget else 0,
                        desc=f"distill {cfg.task} ({cfg.method}" + (f", {cfg.max_minutes:g} min budget)" if budget else ")"),
                        disable=not cfg.progress, dynamic_ncols=True)

    def save_state(self) -> None:
        """What a resumed run needs beyond the demonstrations and the rounds' samples: written after every round
        (to a temporary file first, so an interruption mid-write leaves the previous state)."""
        state = {"model": self.actor_critic.state_dict(), "history": self.history, "frames": self.frames,
                 "config": asdict(self.cfg),
                 "ema": self.ema.state_dict() if self.ema is not None else None,
                 "aux_head": self.aux_head.state_dict() if self.aux_head is not None else None}
        temporary = self.out / (RESUME + ".tmp")
        torch.save(state, temporary)
        os.replace(temporary, self.out / RESUME)

    def restore(self, demos: TensorDictBase) -> None:
        """Back to the end of the last finished round of an interrupted run: weights, log, frames, and the
        buffer refilled in its original order (demonstrations, then each round's samples)."""
        from tensordict import TensorDict

        state = torch.load(self.out / RESUME, map_location="cpu", weights_only=True)
        started = state.get("config")  # None: a state saved before the settings were kept in it
        changed = [] if started is None else changed_settings(started, self.cfg,
                                                              execution=(*EXECUTION_FIELDS, *PATH_FIELDS))
        if changed:
            raise ValueError(f"--resume: {self.out} was started with other settings ({', '.join(changed)}); resume it "
                             "with the settings it started with")
        self.actor_critic.load_state_dict(state["model"])
        if self.ema is not None:
            self.ema.load_state_dict(state["ema"])
        if self.aux_head is not None:
            self.aux_head.load_state_dict(state["aux_head"])
        self.history, self.frames = state["history"], state["frames"]
        self.buffer.extend(demos)
        for r in range(1, len(self.history)):  # rounds/<r> holds all of round r's samples: filtered as they were
            self.extend(TensorDict.load_memmap(self.out / ROUNDS / str(r)))
        # the clock goes on from the last round's (the time lost to the interruption is not counted)
        self.start = time.perf_counter() - self.history[-1]["wall_s"]
        self.bar.update(len(self.history) if not self.budget else 0)

    def extend(self, samples: TensorDictBase) -> int:
        """Add a DAgger round's samples to the buffer (only its successful episodes' with ``drop_failed``);
        returns how many were added."""
        if self.cfg.drop_failed:
            samples = successful_episodes(samples)
        if samples.batch_size[0]:
            self.buffer.extend(samples)
        return samples.batch_size[0]

    def train(self, epochs: int) -> list[float]:
        return train_student(self.actor_critic, self.buffer[:], self.cfg, epochs, self.aux_head, self.ema, self.device)

    def log_round(self, phase: str, beta: float, episodes: int, summary: dict, new_samples: int, losses: list[float],
                  expert_share: float, collect_s: float, train_s: float) -> None:
        """One row of ``log.csv`` (and the checkpoint rewritten); the progress bar moves on."""
        row = {"round": len(self.history), "phase": phase, "beta": beta, "episodes": episodes,
               "collect_success": summary["success_rate"], "collect_max_stage": summary["mean_max_stage"],
               "expert_share": expert_share, "new_samples": new_samples, "buffer": len(self.buffer),
               "expert_frames": self.frames["expert"], "student_frames": self.frames["student"],
               "frames": self.frames["expert"] + self.frames["student"], "loss_first": losses[0], "loss": losses[-1],
               "collect_s": collect_s, "train_s": train_s, "wall_s": time.perf_counter() - self.start}
        self.history.append(row)
        write_log(self.out / "log.csv", self.history)
        save_student(self.out / CHECKPOINT, self.student_net, self.cfg, self.dims, self.frames, self.history)
        self.save_state()
        self.bar.update(min(round(time.perf_counter() - self.start), self.bar.total) - self.bar.n if self.budget else 1)
        self.bar.set_postfix(loss=f"{row['loss']:.4f}", succ=f"{row['collect_success']:.2f}", frames=row["frames"])

    def behaviour_cloning(self, demos: TensorDictBase) -> None:
        """Step 2: the student regresses the expert's labels on the demonstrations."""
        tick, manifest = time.perf_counter(), self.manifest
        self.buffer.extend(demos)
        losses = self.train(self.cfg.epochs)
        expert = {"success_rate": manifest["expert_success_rate"], "mean_max_stage": manifest["expert_mean_max_stage"]}
        self.log_round("bc", 1.0, len(manifest["episodes"]), expert, manifest["samples"], losses, 1.0,
                       0.0 if self.cfg.demos else manifest["wall_time_s"], time.perf_counter() - tick)

    def dagger(self) -> None:
        """Step 3: rounds in which the student drives (with probability 1 - beta) and the expert labels."""
        from dexart_lite.experts import ScriptedPolicy

        cfg, manifest = self.cfg, self.manifest
        scripted, student = ScriptedPolicy(self.env), policy_function(self.student_net)
        episodes_done = len(manifest["episodes"]) + sum(row["episodes"] for row in self.history[1:])
        index_names = manifest["objects"] + [n for n in self.names if n not in manifest["objects"]]  # "object" index
        for r in range(len(self.history), self.rounds + 1):  # round 0 (BC) is history[0]; resumed: the next round
            if self.budget and time.perf_counter() - self.start > self.budget:
                break
            tick = time.perf_counter()
            beta = dagger_beta(cfg, r)
            episodes = episode_list(self.names, cfg.episodes_per_round, np.random.default_rng([cfg.seed, 2, r]))
            samples, results, share = collect_dagger(self.env, scripted, student, episodes, beta,
                                                     np.random.default_rng([cfg.seed, 3, r]), index_names,
                                                     episodes_done, cfg.student_noise)
            episodes_done += len(episodes)
            self.frames["student"] += samples.batch_size[0]
            kept = self.out / ROUNDS / str(r)  # for --resume until the run ends; a folder left by an interruption
            shutil.rmtree(kept, ignore_errors=True)  # during this round's training is this round's, made again
            samples.memmap(prefix=str(kept))
            added = self.extend(samples)
            collected = time.perf_counter()
            losses = self.train(cfg.epochs_per_round)
            self.log_round("dagger", beta, len(results), per_object_summary(results), added, losses,
                           share, collected - tick, time.perf_counter() - collected)

    def close(self) -> None:
        self.bar.close()
        self.env.close()
        shutil.rmtree(self.out / "buffer", ignore_errors=True)

    def forget_resume_state(self) -> None:
        """A finished run needs no resume state: its rounds' samples are most of its disk (~90 MB per toilet round)."""
        shutil.rmtree(self.out / ROUNDS, ignore_errors=True)
        (self.out / RESUME).unlink(missing_ok=True)


def open_distill_run(cfg: DistillConfig) -> tuple[Path, Path]:
    """(run folder, demonstrations folder), refusing a folder that holds a run unless it is resumed, and a resume
    without an unfinished run."""
    out = Path(cfg.out)
    if cfg.resume and not (out / RESUME).is_file():
        raise FileNotFoundError(f"--resume: no unfinished distillation in {out} (no {RESUME}: it finished, or never "
                                "finished its first round)")
    if (out / CHECKPOINT).exists() and not cfg.resume:
        raise ValueError(f"{out} already holds a run; pass --resume to continue an unfinished one, choose another "
                         "--out or delete it")
    demo_path = Path(cfg.demos) if cfg.demos else out / "demos"
    if cfg.demos:
        check_demos(read_manifest(demo_path), cfg)
    out.mkdir(parents=True, exist_ok=True)
    return out, demo_path


def distill(cfg: DistillConfig) -> dict:
    """Demonstrations -> BC -> DAgger rounds -> checkpoint, evaluation, report; see the module docstring."""
    import logging

    logging.getLogger("torchrl").setLevel(logging.WARNING)  # its INFO line on every new storage breaks the bar
    validate(cfg)
    start = time.perf_counter()
    out, demo_path = open_distill_run(cfg)
    device = resolve_device(cfg.device, log=tqdm.write)  # where the student trains
    with torch_threads(cfg.threads or os.cpu_count()):
        torch.manual_seed(cfg.seed)
        # ---- 1. demonstrations (the expert drives, with noise); a resumed run has them
        if not cfg.demos and not cfg.resume:
            collect_demos(cfg.task, cfg.split, cfg.demo_episodes_per_object, cfg.demo_noise, cfg.seed, demo_path,
                          cfg.num_points, cfg.max_episode_steps, cfg.object_names(), cfg.progress, cfg.camera_noise,
                          cfg.imagination, cfg.view_range_degrees(), cfg.encoder == "depth_cnn")
        manifest, demos = read_manifest(demo_path), load_demos(demo_path)
        run = StudentRun(cfg, out, start, device, demos, manifest)
        try:
            if cfg.resume:
                run.restore(demos)
            else:
                run.behaviour_cloning(demos)  # ---- 2.
            run.dagger()  # ---- 3.
        finally:
            run.close()
        student_net, frames, history = run.student_net, run.frames, run.history
        ckpt = save_student(out / CHECKPOINT, student_net, cfg, run.dims, frames, history)
        # the PointNet alone, for `dexart-lite train --pretrained` (the 2-D baseline's CNN has no such use)
        encoder = None if cfg.encoder == "depth_cnn" else save_encoder(encoder_of(student_net), out / "encoder.pt")

        # ---- 4. evaluation on seen and unseen objects, GIF, curve, report
        evals = evaluate_splits(student_net, cfg, out)
        gif = None
        if cfg.gif:
            unseen = objects_lib.list_objects(cfg.task, "unseen")[0].name
            gif = record_gif(student_net, cfg.task, out / "episode.gif", "unseen", unseen, cfg.eval_seed,
                             cfg.env_kwargs())["path"]
    curve = plot_rounds(history, evals, out / "rounds.png", title=f"{cfg.method} on {cfg.task}, {encoder_label(cfg.encoder)}")
    wall = time.perf_counter() - run.start  # a resumed run's clock includes its earlier rounds
    report = write_report(out / "report.md", cfg, manifest, history, evals, curve, wall, gif)
    run.forget_resume_state()  # only now: a run stopped in its evaluation resumes after its last round, evaluates
    by_split = {e["split"]: e for e in evals}
    return {"checkpoint": str(ckpt), "encoder": str(encoder) if encoder else None, "report": str(report),
            "curve": str(curve), "gif": gif, "log": str(out / "log.csv"), "demos": str(demo_path),
            "device": device.type, "seen_success": by_split["seen"]["success_rate"] if evals else None,
            "unseen_success": by_split["unseen"]["success_rate"] if evals else None,
            "expert_frames": frames["expert"], "student_frames": frames["student"], "wall_time_s": wall,
            "eval": by_split, "history": history}


def check_demos(manifest: dict, cfg: DistillConfig) -> None:
    """``ValueError`` unless the demonstrations of ``manifest`` fit the run of ``cfg``."""
    ours = cfg.view_range_degrees()
    for key, theirs, mine in (("imagination", manifest.get("imagination", True), cfg.imagination),
                              ("view_range", manifest.get("view_range"), list(ours) if ours else None)):
        if theirs != mine:
            raise ValueError(f"--demos {cfg.demos} has {key} {theirs!r}, this run has {mine!r}")
    for key in ("task", "num_points"):
        if manifest[key] != getattr(cfg, key):
            raise ValueError(f"--demos {cfg.demos} has {key} {manifest[key]!r}, this run has {getattr(cfg, key)!r}")


def save_student(path: Path, actor_critic: ActorValueOperator, cfg: DistillConfig, dims: dict, frames: dict,
                 history: list[dict]) -> Path:
    """The student as a PPO checkpoint (``rl.checkpoint``): ``dexart-lite eval`` and ``render`` load it."""
    return save_checkpoint(path, {"config": asdict(cfg), "dims": dims, "model": actor_critic.state_dict(),
                                  "frames": frames["expert"] + frames["student"], "batches": len(history),
                                  "history": history, "trainer": "distill"})


def write_log(path: Path, history: list[dict]) -> Path:
    """One CSV row per round (0: BC on the demonstrations)."""
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(history[0]))
        writer.writeheader()
        writer.writerows(history)
    return path


# ----------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from dexart_lite.cli import add_config_arguments

    add_config_arguments(parser, DistillConfig)


def run(args: argparse.Namespace) -> int:
    from dexart_lite.cli import config_from_args

    result = distill(config_from_args(DistillConfig, args))
    print(f"checkpoint: {result['checkpoint']}\nreport:     {result['report']}\ncurve:      {result['curve']}")
    print(f"expert frames {result['expert_frames']}, student frames {result['student_frames']}, "
          f"{result['wall_time_s'] / 60:.1f} min")
    for split, res in result["eval"].items():
        print(f"{split} success: {res['success_rate']:.2f} ({res['episodes']} episodes)")
    return 0
