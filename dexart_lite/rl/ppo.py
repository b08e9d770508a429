"""Point-cloud PPO with torchrl: ``PPOConfig`` and ``train(cfg)``.

    dexart-lite train --task laptop --encoder small --frames 1000000 --workers 2 --out runs/laptop
    dexart-lite train --task laptop --preset cpu --frames 60000 --out runs/laptop_cpu

``train`` reads top to bottom: env factory and actor-critic -> collector -> GAE -> ClipPPOLoss ->
the minibatch loop -> logging -> checkpoint; then the evaluation on seen and unseen objects and
``report.md``. The defaults of ``PPOConfig`` are DexArt's PPO settings (``preset="faithful"``);
``PRESETS["cpu"]`` is the measured cheaper variant used by the demo (see ``PRESETS``).

Collection (``--backend``): ``process`` runs ``MultiSyncCollector`` with ``--workers`` spawned
processes (an in-process ``Collector`` for 0 or 1 worker); ``distributed`` hands it to torchrl's
``DistributedCollector`` (torch.distributed, gloo; here launched with the ``mp`` launcher on one
machine: see that class for SLURM via submitit); ``ray`` to torchrl's ``RayCollector``, an
optional extra::

    pip install ".[distributed]"            # installs ray
    ray start --head                         # on the head node; `ray start --address=HEAD:6379` on the others
    dexart-lite train --backend ray --ray-address auto --workers 8 ...

Everything is synchronous, as in DexArt's SB3: collect a batch with the current weights, update,
push the weights to the collectors, collect again.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import importlib.util
import math
import time
from dataclasses import asdict, dataclass, field
from functools import partial
from pathlib import Path

import torch
from tqdm import tqdm

from dexart_lite import objects as objects_lib
from dexart_lite.demos import load_demos
from dexart_lite.models.actor_critic import (HEAD_HIDDEN, POINTS_KEY, STATE_HIDDEN, STATE_KEY, Acting,
                                             action_log_std, architecture, encoder_of, make_actor_critic,
                                             set_action_log_std, trunk_of)
from dexart_lite.models.pointnet import ENCODER_SIZES, PointNetEncoder, load_encoder
from dexart_lite.envs.rewards import REWARD_MODES
from dexart_lite.registration import HAND_MODES, OBSERVATIONS, TASKS
from dexart_lite.rl.curriculum import Curriculum, CurriculumConfig, find_demos, guide_demos, send_level
from dexart_lite.rl.checkpoint import checkpoint_path, load_checkpoint, network_encoder, policy_function, save_checkpoint
from dexart_lite.rl.env import env_dims, make_env
from dexart_lite.rl.sil import SelfImitationBuffer, sil_loss
from dexart_lite.utils import (DEVICES, check_choice, optimizer_to, release_freed_memory, resident_mb, resolve_device,
                               to_cpu)

BACKENDS = ("process", "distributed", "ray")
CHECKPOINT = "checkpoint.pt"
LOSS_KEYS = ("loss_objective", "loss_critic", "loss_entropy", "entropy", "kl_approx", "clip_fraction",
             "explained_variance")
# what the loss reads from a batch; the rest (next observations, info) is dropped before the epochs
BATCH_KEYS = ("point_cloud", "observation", "action", "action_log_prob", "advantage", "value_target")
SIL_KEYS = ("loss_sil", "loss_sil_value", "sil_positive")  # logged with --sil-coef (rl/sil.py)


@dataclass
class PPOConfig:
    """One training run. Defaults = DexArt's PPO (``examples/train.py`` + SB3 PPO defaults)."""

    task: str = field(default="laptop", metadata={"help": f"one of {', '.join(TASKS)}"})
    encoder: str = field(default="small", metadata={"help": "PointNet size: small, medium, large"})
    device: str = field(default="cpu", metadata={"help": "where the networks, the loss and the optimizer live: cpu, "
                        "cuda or auto (cuda where there is one); collection and evaluation stay on the CPU"})
    frames: int = field(default=1_000_000, metadata={"help": "total env frames (DexArt: ~15M on Laptop)"})
    frames_per_batch: int = field(default=20_000, metadata={"help": "frames collected per PPO update (DexArt: 10 envs x 2000)"})
    workers: int = field(default=2, metadata={"help": "collector processes (0 or 1: collect in this process)"})
    backend: str = field(default="process", metadata={"help": "process, distributed (torch.distributed) or ray"})
    lr: float = field(default=1e-4, metadata={"help": "Adam learning rate, constant"})
    gamma: float = 0.99
    lmbda: float = field(default=0.95, metadata={"help": "GAE lambda"})
    clip_epsilon: float = 0.2
    epochs: int = field(default=10, metadata={"help": "passes over each batch"})
    minibatch: int = 500
    vf_coef: float = field(default=0.5, metadata={"help": "value-loss coefficient"})
    entropy_coef: float = 0.0
    init_log_std: float = field(default=0.0, metadata={"help": "initial log std of the actions (DexArt: 0, std 1)"})
    max_grad_norm: float = 0.5
    adam_eps: float = 1e-5
    normalize_advantage: bool = field(default=True, metadata={"help": "per minibatch, as SB3"})
    split: str = field(default="seen", metadata={"help": "training objects: seen or seen_half"})
    obs: str = field(default="cloud", metadata={"help": "cloud (DexArt: point cloud + state, PointNet) or state: a "
                     "diagnostic, the state vector plus the privileged object state and no camera, an MLP policy "
                     "(--encoder is then unused); it measures how learnable a task's reward is apart from perception"})
    head: str = field(default="64,64", metadata={"help": "hidden widths of the policy and value MLPs (DexArt: 64,64)"})
    state_hidden: int = field(default=64, metadata={"help": "width of the trunk's state MLP (DexArt: 64)"})
    reward: str = field(default="dexart", metadata={"help": "dexart; shaped: plus stage-2 terms toward the grasp "
                        "(envs.rewards.shaping; not DexArt's); capped: the terminal bonus counts progress up to the "
                        "success threshold only (not DexArt's); flat: a success pays a fixed horizon * 1.2 * threshold, whatever the "
                        "step (not DexArt's); evaluation reports success either way"})
    hand: str = field(default="joints", metadata={"help": "joints (DexArt: 16 hand joint targets, a 22-D action) or "
                      "synergy: 3 numbers close knuckles, finger curl and thumb (robot.synergy_targets; a 9-D action, "
                      "not DexArt's)"})
    num_points: int = field(default=512, metadata={"help": "observed points per cloud (+96 imagined)"})
    max_episode_steps: int | None = field(default=None, metadata={"help": "episode length (None: the task's 250); for quick tests"})
    seed: int = 0
    out: str = field(default="runs/ppo", metadata={"help": "output folder (checkpoint, logs, report)"})
    checkpoint_every: int = field(default=5, metadata={"help": "save a checkpoint every N batches"})
    max_minutes: float | None = field(default=None, metadata={"help": "stop training after the batch that crosses this many minutes"})
    resume: bool = field(default=False, metadata={"help": "continue the run in --out from its checkpoint"})
    pretrained: str | None = field(default=None, metadata={"help": "encoder file (save_encoder) loaded strictly into the trunk"})
    init_from: str | None = field(default=None, metadata={"help": "checkpoint whose whole actor-critic starts the run "
                                  "(a `dexart-lite distill` student or a PPO run of the same task and encoder), loaded "
                                  "strictly with its architecture; the action log-std is then set to --init-log-std"})
    critic_lr: float | None = field(default=None, metadata={"help": "learning rate of the value head (None: --lr)"})
    target_kl: float | None = field(default=None, metadata={"help": "stop a batch's epochs once the approximate KL "
                                    "to the collecting policy exceeds this (SB3's target_kl; None: never)"})
    reward_scale: float = field(default=1.0, metadata={"help": "rewards are multiplied by this before GAE, so "
                                "the critic fits values of order 1 (DexArt: 1; its success bonus reaches ~300). "
                                "Logged returns stay unscaled"})
    critic_detach: bool = field(default=False, metadata={"help": "the value loss trains the value head only: its "
                                "gradient does not reach the shared trunk (DexArt/SB3: it does). A critic that is "
                                "still wrong then cannot reshape the features a distilled actor relies on"})
    critic_warmup: int = field(default=0, metadata={"help": "first batches in which only the value head learns (the "
                               "actor, trunk included, is frozen while the critic is still wrong)"})
    bc_coef: float = field(default=0.0, metadata={"help": "weight of a behaviour-cloning term (MSE of the action mean "
                           "to the expert labels of --bc-demos) added to the PPO loss; 0: off"})
    bc_decay: float = field(default=0.8, metadata={"help": "the BC weight is multiplied by this after every batch"})
    bc_demos: str | None = field(default=None, metadata={"help": "demonstrations folder (`dexart-lite data demos`, "
                                 "or a distill run's demos/) for the BC term"})
    demo_episodes: int = field(default=0, metadata={"help": "guide demonstrations per training object, collected "
                               "at the start in the run's observation (rl/curriculum.guide_demos; the scripted "
                               "expert, privileged, training only): the data of --bc-warmstart and of --bc-coef "
                               "(instead of --bc-demos). Counted apart from the online frames. 0: none"})
    demo_noise: float = field(default=0.1, metadata={"help": "std of the noise on the demonstrations' executed "
                              "actions (the labels stay clean)"})
    bc_warmstart: int = field(default=0, metadata={"help": "epochs of behaviour cloning (MSE of the action mean "
                              "to the labels) on the --demo-episodes data before the first batch; the inputs are "
                              "normalised with the demonstrations' statistics. 0: off"})
    dagger_rounds: int = field(default=0, metadata={"help": "after --bc-warmstart: rounds in which the cloned "
                               "policy drives --demo-episodes episodes per object (deterministic actions), the "
                               "guide labels every state, and the policy is cloned again on all the data (DAgger); "
                               "with --init-from the loaded policy drives and is not retrained (the rounds only "
                               "collect the BC term's data). Their steps count as demonstration frames. 0: off"})
    anchor_coef: float = field(default=0.0, metadata={"help": "weight of a KL penalty to the --init-from policy "
                               "on the batch's visited states, KL(pi || pi_init) summed over the action dims (as "
                               "RLHF's KL to the reference model); it keeps the fine-tuned policy near the student "
                               "where the noisy policy gradient has no consistent direction. 0: off (DexArt: no "
                               "initial policy)"})
    anchor_decay: float = field(default=1.0, metadata={"help": "the anchor's weight is multiplied by this after "
                                "every batch past the critic warm-up (1: a constant anchor, which holds the student "
                                "but also caps what RL can add; < 1 lets go of it slowly)"})
    anchor_floor: float = field(default=0.0, metadata={"help": "the decaying anchor's weight stops falling at this "
                                "value (0: let go entirely; between 0 and --anchor-coef: a weaker anchor that still "
                                "bounds how far RL drifts from the student)"})
    obs_norm_steps: int = field(default=0, metadata={"help": "steps of the initial policy whose observations fix "
                                "the network's input normalisation before training (torchrl's ObservationNorm."
                                "init_stats: per entry of the state vector, one centre and scale for the cloud); "
                                "0: raw inputs (DexArt)"})
    sil_coef: float = field(default=0.0, metadata={"help": "weight of the self-imitation loss (rl/sil.py; Oh et al. "
                            "2018): every minibatch step also imitates the actions of the best episodes collected so "
                            "far where their return beat the critic's estimate. 0: off (DexArt: no replay)"})
    sil_capacity: int = field(default=20_000, metadata={"help": "steps of the best episodes kept for --sil-coef (in "
                              "memory; a resumed run starts with an empty buffer)"})
    sil_value_coef: float = field(default=0.01, metadata={"help": "weight of the self-imitation value term (SIL's 0.01)"})
    curriculum: str = field(default="none", metadata={"help": "start-state curriculum (rl/curriculum.py): none "
                            "(DexArt: every episode from the true reset), uniform (the guide acts h ~ U[0, H] steps "
                            "first) or reverse (RFCL: a start frontier per demonstration moves back after "
                            "successes). The guide's steps are never collected nor counted"})
    curriculum_horizon: int = field(default=130, metadata={"help": "uniform: H, the largest number of guide steps"})
    curriculum_demos: int = field(default=11, metadata={"help": "reverse: demonstrations, (seed, object) pairs the "
                                  "guide solves, one frontier each"})
    curriculum_step: int = field(default=5, metadata={"help": "reverse: steps a frontier moves back (RFCL: 4-8)"})
    curriculum_successes: int = field(default=3, metadata={"help": "reverse: successes in a row from a frontier "
                                      "before it moves (RFCL: 3)"})
    curriculum_backoff: int = field(default=0, metadata={"help": "reverse: failures in a row from a frontier before it "
                                    "moves forward by --curriculum-step (0: never, RFCL; Florensa et al. keep starts "
                                    "at 0.1-0.9 success)"})
    curriculum_true_resets: float = field(default=0.1, metadata={"help": "reverse: share of episodes that start "
                                          "from the true reset (all once 90%% of the frontiers are at 0)"})
    curriculum_probe: float = field(default=0.0, metadata={"help": "reverse: share of the guided episodes that start "
                                    "at a uniform step before their frontier; a success there moves the frontier to "
                                    "it (0: none, RFCL)"})
    guide: str = field(default="expert", metadata={"help": "who acts before the learner: expert (the scripted, "
                       "privileged solver; training only) or a checkpoint file"})
    guide_render: bool = field(default=False, metadata={"help": "render the camera on every guide step (False: "
                               "only on the last; the same physical state, other random draws in the cloud)"})
    freeze_encoder: bool = field(default=False, metadata={"help": "keep the PointNet fixed (DexArt fine-tunes it)"})
    eval_episodes: int = field(default=10, metadata={"help": "evaluation episodes per object at the end (0: none)"})
    eval_seed: int = 100
    gif: bool = field(default=False, metadata={"help": "save a GIF of one evaluation episode"})
    threads: int = field(default=0, metadata={"help": "torch threads of the learner (0: all cores)"})
    tcp_port: int = field(default=10123, metadata={"help": "distributed backend: rendezvous port on the master"})
    ray_address: str | None = field(default=None, metadata={"help": "ray backend: cluster address (None: start a local Ray)"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})
    trim_memory: bool = field(default=True, metadata={"help": "after each batch hand the heap's freed pages back to the "
                              "OS (glibc malloc_trim): without it resident memory grows by GBs over a long run"})

    def head_widths(self) -> tuple[int, ...]:
        """``head`` as integers; a ValueError names the expected form."""
        try:
            widths = tuple(int(w) for w in self.head.split(","))
        except ValueError:
            widths = ()
        if not widths or min(widths) < 1:
            raise ValueError(f"--head must be comma-separated positive widths such as 64,64, not {self.head!r}")
        return widths

    def env_kwargs(self) -> dict:
        """Keyword arguments of the env that the training, evaluation and GIF envs share."""
        kwargs = {"num_points": self.num_points}
        if self.reward != "dexart":
            kwargs["reward"] = self.reward
        if self.obs != "cloud":
            kwargs["observation"] = self.obs
        if self.hand != "joints":
            kwargs["hand"] = self.hand
        if self.max_episode_steps:
            kwargs["max_episode_steps"] = self.max_episode_steps
        return kwargs


# Named presets: the fields they change. Measured in benchmarks/perf/bench_training.py (see README there).
PRESETS: dict[str, dict] = {
    "faithful": {},
    # Same algorithm, 5x smaller batches (4k frames: 2 workers x 2000 steps, 8 full episodes) and 5 epochs:
    # a PPO update every ~20 s instead of every ~3 min, and half the gradient steps per frame.
    "cpu": {"frames_per_batch": 4000, "epochs": 5},
    # PPO from a distilled student (`--init-from`), every departure from DexArt against the collapse of a
    # cloned policy: the cpu preset with a small action std (0.1, not 1: the student's actions are
    # millimetre-precise), lr 3e-5 (not 1e-4), 5 batches in which only the critic learns (the student's
    # value head was never trained), the value loss kept out of the shared trunk (critic_detach), rewards
    # x 0.01 (the success bonus reaches ~300) with a critic lr of 1e-3, SB3's KL early stop at 0.01, and
    # DexArt's 3 evaluation episodes per object of the distillation benchmark. Measured on a laptop student
    # (0.42 / 0.44): without the last four guards it collapsed to 0.03 / 0.00 in 100k frames; with them it
    # ends at 0.42 / 0.22 after 300k, the success of its collected episodes falling from 0.45 to about 0.2
    # (benchmarks/results/rl/finetune_laptop_{collapse,klstop,klstop_bc}.json). Held out (20 episodes per
    # object, env seed 1000, 2 seeds): on faucets it raises seen success and keeps unseen (0.60 / 0.57 ->
    # 0.69 / 0.56, finetune_faucet.json); with --anchor-coef 1 the laptop students improve on both splits
    # (0.63 / 0.65 -> 0.70 / 0.73, finetune_laptop_anchor.json).
    # From scratch on 2 cores: the cpu preset with the departures the state-only diagnostic
    # uses (lr 3e-4, not 1e-4; rewards x 0.01, not x 1, so the critic fits values of order 1 although the
    # success bonus reaches ~300; initial action std 0.3, not 1: with std 1 even the expert never lifts
    # a lid, benchmarks/experts/exploration_noise.py) plus a fixed input normalisation from 2,000 steps of the
    # initial policy (DexArt feeds raw inputs; "What matters in on-policy RL" and the SB3 zoo normalise).
    # Measured against the same settings without normalisation (benchmarks/rl/state_diagnostic.py, state only,
    # 2 seeds, 300k frames): no change; neither opens a laptop, and on faucets both collect a success now
    # and then (best batch 0.06-0.24) while the deterministic policy opens none. A starting point, not a recipe.
    "fast": {"frames_per_batch": 4000, "epochs": 5, "lr": 3e-4, "reward_scale": 0.01, "init_log_std": -1.2,
             "obs_norm_steps": 2000},
    "finetune": {"frames_per_batch": 4000, "epochs": 5, "init_log_std": -2.3, "lr": 3e-5, "critic_warmup": 5,
                 "critic_detach": True, "reward_scale": 0.01, "critic_lr": 1e-3, "target_kl": 0.01,
                 "eval_episodes": 3},
    # `make demo`: the cpu preset on Laptop for a fixed time budget, then 2 evaluation episodes per
    # object on the seen and the unseen laptops and a GIF; <= 10 minutes in all on 2 cores.
    "demo": {"frames_per_batch": 4000, "epochs": 5, "task": "laptop", "frames": 200_000, "max_minutes": 6.0,
             "eval_episodes": 2, "gif": True, "out": "demo_out"},
}


def preset(name: str, **overrides) -> PPOConfig:
    """``PPOConfig`` of a named preset, with ``overrides`` applied."""
    check_choice("preset", name, PRESETS)
    return dataclasses.replace(PPOConfig(), **{**PRESETS[name], **overrides})


def validate(cfg: PPOConfig) -> None:
    check_choice("task", cfg.task, TASKS)
    check_choice("encoder size", cfg.encoder, ENCODER_SIZES)
    check_choice("backend", cfg.backend, BACKENDS)
    check_choice("training split", cfg.split, ("seen", "seen_half"))
    check_choice("reward", cfg.reward, REWARD_MODES)
    check_choice("observation", cfg.obs, OBSERVATIONS)
    check_choice("device", cfg.device, DEVICES)
    if cfg.device == "cuda":
        resolve_device(cfg.device)  # no CUDA here: one line, before anything is built
    check_choice("hand", cfg.hand, HAND_MODES)
    if cfg.obs == "state" and (cfg.pretrained or cfg.freeze_encoder):
        raise ValueError("--obs state has no PointNet: drop --pretrained / --freeze-encoder")
    cfg.head_widths()
    for name in ("frames", "frames_per_batch", "epochs", "minibatch", "num_points", "checkpoint_every", "state_hidden"):
        if getattr(cfg, name) < 1:
            raise ValueError(f"{name} must be >= 1, got {getattr(cfg, name)}")
    if cfg.workers < 0 or (cfg.backend != "process" and cfg.workers < 1):
        raise ValueError(f"workers must be >= 0 (>= 1 for the {cfg.backend} backend), got {cfg.workers}")
    if cfg.frames_per_batch % cfg.minibatch:  # a leftover minibatch of 1 would normalise its advantage to NaN
        raise ValueError(f"minibatch ({cfg.minibatch}) must divide frames_per_batch ({cfg.frames_per_batch})")
    if cfg.frames_per_batch % max(cfg.workers, 1):
        raise ValueError(f"frames_per_batch ({cfg.frames_per_batch}) must be a multiple of workers ({cfg.workers})")
    if not math.isfinite(cfg.init_log_std):
        raise ValueError(f"init_log_std must be a finite number, got {cfg.init_log_std}")
    if cfg.pretrained and not Path(cfg.pretrained).is_file():
        raise FileNotFoundError(f"pretrained encoder not found: {cfg.pretrained}")
    if cfg.init_from and not checkpoint_path(cfg.init_from).is_file():
        raise FileNotFoundError(f"--init-from: checkpoint not found: {cfg.init_from}")
    if cfg.init_from and cfg.pretrained:
        raise ValueError("--init-from already holds an encoder: drop --pretrained")
    if cfg.critic_warmup < 0 or not 0.0 < cfg.bc_decay <= 1.0 or not cfg.bc_coef >= 0.0:
        raise ValueError(f"need critic_warmup >= 0, 0 < bc_decay <= 1 and bc_coef >= 0, got {cfg.critic_warmup}, "
                         f"{cfg.bc_decay}, {cfg.bc_coef}")
    if not (math.isfinite(cfg.reward_scale) and cfg.reward_scale > 0):
        raise ValueError(f"reward_scale must be a finite number > 0, got {cfg.reward_scale}")
    for name in ("critic_lr", "target_kl"):
        value = getattr(cfg, name)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a finite number > 0 (or None), got {value}")
    for name in ("anchor_coef", "sil_coef", "sil_value_coef"):
        if not (math.isfinite(getattr(cfg, name)) and getattr(cfg, name) >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {getattr(cfg, name)}")
    if cfg.anchor_coef > 0 and not cfg.init_from:
        raise ValueError("anchor_coef > 0 needs --init-from (the policy to stay near)")
    if not 0.0 < cfg.anchor_decay <= 1.0:
        raise ValueError(f"anchor_decay must be in (0, 1], got {cfg.anchor_decay}")
    if not (math.isfinite(cfg.anchor_floor) and 0.0 <= cfg.anchor_floor <= cfg.anchor_coef):
        raise ValueError(f"anchor_floor must be in [0, anchor_coef={cfg.anchor_coef}], got {cfg.anchor_floor}")
    if cfg.sil_capacity < 1:
        raise ValueError(f"sil_capacity must be >= 1 step, got {cfg.sil_capacity}")
    if cfg.obs_norm_steps < 0:
        raise ValueError(f"obs_norm_steps must be >= 0, got {cfg.obs_norm_steps}")
    if cfg.obs_norm_steps and cfg.init_from:
        raise ValueError("--init-from brings its own input normalisation: drop --obs-norm-steps")
    if cfg.bc_coef > 0 and not (cfg.bc_demos or cfg.demo_episodes):
        raise ValueError("bc_coef > 0 needs --bc-demos (a demonstrations folder) or --demo-episodes")
    if cfg.demo_episodes < 0 or cfg.bc_warmstart < 0 or not (math.isfinite(cfg.demo_noise) and cfg.demo_noise >= 0):
        raise ValueError(f"need demo_episodes >= 0, bc_warmstart >= 0 and a finite demo_noise >= 0, got "
                         f"{cfg.demo_episodes}, {cfg.bc_warmstart}, {cfg.demo_noise}")
    if cfg.dagger_rounds < 0 or (cfg.dagger_rounds and not (cfg.bc_warmstart or cfg.init_from)):
        raise ValueError(f"dagger_rounds must be >= 0 and needs --bc-warmstart (the epochs of each round) or "
                         f"--init-from (the policy that drives), got {cfg.dagger_rounds}")
    if cfg.bc_warmstart and not cfg.demo_episodes:
        raise ValueError("bc_warmstart needs --demo-episodes (the data it clones)")
    if cfg.demo_episodes and (cfg.bc_demos or cfg.obs_norm_steps):
        raise ValueError("--demo-episodes brings its own data and input normalisation: drop --bc-demos and "
                         "--obs-norm-steps")
    if cfg.bc_warmstart and cfg.init_from:
        raise ValueError("--init-from is a trained policy already: drop --bc-warmstart (its --demo-episodes and "
                         "--dagger-rounds then only collect the BC term's data)")
    curriculum_config(cfg).validate()
    if cfg.curriculum != "none" and cfg.backend != "process":
        raise ValueError(f"a curriculum needs the process backend (its level reaches the workers through the "
                         f"collector), got backend {cfg.backend!r}")
    if cfg.backend == "ray" and importlib.util.find_spec("ray") is None:
        raise RuntimeError("the ray backend needs Ray, an optional extra: pip install '.[distributed]' "
                           "(or pip install 'dexart_lite[distributed]')")


def curriculum_config(cfg: PPOConfig) -> CurriculumConfig:
    return CurriculumConfig(cfg.curriculum, cfg.curriculum_horizon, cfg.curriculum_demos, cfg.curriculum_step,
                            cfg.curriculum_successes, cfg.curriculum_backoff, cfg.curriculum_true_resets,
                            probe=cfg.curriculum_probe, guide=cfg.guide)


def make_curriculum(cfg: PPOConfig) -> Curriculum | None:
    """The run's start-state schedule (None without one); ``reverse`` first finds its demonstrations: the
    guide's solved episodes on the training objects (seeds from ``cfg.seed``)."""
    if cfg.curriculum == "none":
        return None
    ccfg = curriculum_config(cfg)
    kwargs = {k: v for k, v in cfg.env_kwargs().items() if k != "observation"}
    demos = find_demos(cfg.task, ccfg.demos, cfg.split, cfg.seed, kwargs, cfg.guide) if ccfg.schedule == "reverse" else None
    return Curriculum(ccfg, demos)


def make_collector(cfg: PPOConfig, env_fns: list, actor_critic, total_frames: int):
    """The collector of ``cfg.backend``; worker ``i`` builds its own env with ``env_fns[i]``. It acts with
    ``Acting(actor_critic)``: the whole actor-critic's outputs (action and value in one trunk pass) on
    the same weights, without tensordict's per-module overhead."""
    from torchrl.collectors import Collector, MultiSyncCollector

    policy = Acting(actor_critic)
    common = dict(frames_per_batch=cfg.frames_per_batch, total_frames=total_frames)
    if cfg.backend == "process" and cfg.workers <= 1:
        return Collector(env_fns[0], policy, **common)
    if cfg.backend == "process":  # num_threads: keep this process's torch threads for the update
        return MultiSyncCollector(env_fns, policy, num_threads=torch.get_num_threads(), **common)
    if cfg.backend == "distributed":
        from torchrl.collectors.distributed import DistributedCollector

        return DistributedCollector(env_fns, policy, launcher="mp", sync=True, tcp_port=str(cfg.tcp_port), **common)
    from torchrl.collectors.distributed import RayCollector  # cfg.backend == "ray", checked by validate

    return RayCollector(env_fns, policy, sync=True, remote_configs={"num_cpus": 1},
                        ray_init_config={"address": cfg.ray_address} if cfg.ray_address else None, **common)


def add_next_values(data, value_operator) -> None:
    """Write ``("next", "state_value")`` for GAE, from the values the collector recorded.

    The collector runs the whole actor-critic, so ``data["state_value"]`` already holds V(s_t)
    computed with the current weights (as SB3's rollout buffer). V(s_{t+1}) is the next entry in
    time, except where the next observation is not the next root one: after a time-limit
    truncation (bootstrapped, as SB3) and at the end of the batch; only those are evaluated here.
    After a termination the next value is masked out by GAE. data: (workers, T) or (T,).
    """
    value = data["state_value"]  # (..., T, 1)
    next_value = torch.roll(value, shifts=-1, dims=-2).clone()
    fresh = data["next", "truncated"].squeeze(-1).clone()  # (..., T)
    fresh[..., -1] = True
    next_value[fresh] = value_operator(data["next"][fresh])["state_value"]
    data["next", "state_value"] = next_value


def batch_stats(data) -> dict:
    """Episode return / success of the episodes that ended in ``data``, and the fraction of steps per stage."""
    done = data["next", "done"].squeeze(-1)
    stage = data["next", "stage"]
    stats = {f"stage{s}_frac": float((stage == s).float().mean()) for s in (1, 2, 3)}
    stats["progress"] = float(data["next", "progress"].mean())
    stats["episodes"] = int(done.sum())
    ended = stats["episodes"] > 0
    stats["episode_return"] = float(data["next", "episode_reward"].squeeze(-1)[done].mean()) if ended else math.nan
    stats["success_rate"] = float(data["next", "episode_success"][done].float().mean()) if ended else math.nan
    stats["episode_length"] = float(data["next", "step_count"].squeeze(-1)[done].float().mean()) if ended else math.nan
    return stats


def value_error_at_start(data, gamma: float) -> dict:
    """How well the critic knows where an episode starts: mean |V(s_0) - G_0| over the episodes that start and
    end inside ``data`` (a collector batch after ``advantages``: rewards scaled as the critic sees them), for the
    episodes from the true reset (``value_error_h0``) and for those the guide handed over (``value_error_guided``,
    h > 0: the error at the switch). ``G_0`` is the discounted return the episode collected (a time-limit cut
    is not bootstrapped; the state vector carries t / T). A key is left out where no such episode ended (the
    history stays free of NaN, so a resumed run's history compares equal to the saved one)."""
    time_dim = data.ndim - 1
    reward = data["next", "reward"].squeeze(-1).reshape(-1, data.shape[time_dim])  # (trajectories, T)
    done = data["next", "done"].squeeze(-1).reshape(reward.shape)
    first = data["is_init"].squeeze(-1).reshape(reward.shape)
    value = data["state_value"].squeeze(-1).reshape(reward.shape)
    guided = data["next", "start_step"].reshape(reward.shape) > 0
    returns, running = torch.zeros_like(reward), torch.zeros(reward.shape[0])
    for t in reversed(range(reward.shape[1])):
        running = reward[:, t] + gamma * running * (~done[:, t])
        returns[:, t] = running
    # complete: a done at this step or later in the same trajectory of the batch
    complete = torch.flip(torch.cummax(torch.flip(done.int(), [1]), 1).values, [1]).bool()
    error = (value - returns).abs()
    out = {}
    for name, mask in (("value_error_h0", first & complete & ~guided), ("value_error_guided", first & complete & guided)):
        if bool(mask.any()):
            out[name] = float(error[mask].mean())
    return out


@dataclass
class Learner:
    """The actor-critic and everything that updates it (built once per run by ``build_learner``)."""

    actor_critic: torch.nn.Module
    loss_module: torch.nn.Module  # ClipPPOLoss
    optimizer: torch.optim.Optimizer
    trainable: list
    gae: torch.nn.Module
    value_operator: torch.nn.Module  # V(s) alone, for the bootstrap values GAE needs
    dims: dict  # num_points, state_dim, action_dim of the env; head and normalize of the network
    bc_data: object = None  # the --bc-demos samples (a memory-mapped TensorDict) or None
    anchor: torch.nn.Module | None = None  # a frozen copy of the --init-from policy (--anchor-coef) or None
    sil: SelfImitationBuffer | None = None  # the best episodes so far (--sil-coef) or None
    critic: torch.nn.Module | None = None  # the value head the loss trains (fed detached features with --critic-detach)
    demos: dict | None = None  # --demo-episodes: their frames (not online frames), the guide's success, BC losses
    device: torch.device = torch.device("cpu")  # of the networks, the loss and the optimizer (``Learner.to``)

    def to(self, device: torch.device) -> torch.nn.Module:
        """Move the networks (the loss module's too) to ``device``; the optimizer keeps the same parameters.
        Returns the module the collectors and evaluation act with: the actor-critic itself on the CPU, else a
        CPU copy of it that ``sync_acting`` refreshes after every update."""
        self.device = torch.device(device)
        if self.device.type == "cpu":
            return self.actor_critic
        acting = copy.deepcopy(self.actor_critic)
        for module in (self.actor_critic, self.loss_module, self.value_operator, self.critic, self.anchor):
            if module is not None:
                module.to(self.device)
        optimizer_to(self.optimizer, self.device)  # a resumed run's Adam moments were loaded on the CPU
        return acting

    def sync_acting(self, acting: torch.nn.Module) -> None:
        """The CPU copy ``acting`` (``Learner.to``) takes the learner's current weights."""
        if acting is not self.actor_critic:
            acting.load_state_dict(self.actor_critic.state_dict())


def open_run(cfg: PPOConfig) -> Path:
    """Check ``cfg`` and the output folder (a finished run is never overwritten without --resume)."""
    validate(cfg)
    out = Path(cfg.out)
    if (out / CHECKPOINT).exists() and not cfg.resume:
        raise ValueError(f"{out} already holds a run; pass --resume to continue it or choose another --out")
    if cfg.resume and not (out / CHECKPOINT).exists():
        raise FileNotFoundError(f"--resume: no checkpoint in {out}")
    out.mkdir(parents=True, exist_ok=True)
    return out


def initial_weights(cfg: PPOConfig, state_dim: int, action_dim: int) -> tuple[dict, dict | None]:
    """(``make_actor_critic`` keywords, weights) of ``--init-from`` (its architecture); without it the
    architecture of ``--head`` and ``--state-hidden`` and no weights."""
    own = {"head": cfg.head_widths(), "state_hidden": cfg.state_hidden}
    if not cfg.init_from:
        return own, None
    if own != {"head": HEAD_HIDDEN, "state_hidden": STATE_HIDDEN}:
        raise ValueError("--init-from brings its own architecture: drop --head / --state-hidden")
    payload = load_checkpoint(cfg.init_from)
    source = payload["config"]
    if (source["task"], source["encoder"]) != (cfg.task, cfg.encoder):
        raise ValueError(f"--init-from: {cfg.init_from} is a {source['encoder']} {source['task']} network, "
                         f"not {cfg.encoder} {cfg.task}")
    if (payload["dims"]["state_dim"], payload["dims"]["action_dim"]) != (state_dim, action_dim):
        raise ValueError(f"--init-from: {cfg.init_from} has state/action sizes {payload['dims']['state_dim']}/"
                         f"{payload['dims']['action_dim']}, this env {state_dim}/{action_dim}")
    return architecture(payload["dims"]), payload["model"]


def init_normalization(actor_critic, env_fn, steps: int, seed: int) -> None:
    """Fix the trunk's input normalisation (``Trunk.set_normalization``) from ``steps`` steps of the
    initial, stochastic policy in one env seeded with ``seed``, as torchrl's ``ObservationNorm.init_stats``
    does: the statistics then stay fixed, so every batch is collected and learnt on the same inputs."""
    from torchrl.envs.utils import ExplorationType, set_exploration_type

    env = env_fn(seed=seed)
    try:
        with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
            td = env.rollout(steps, actor_critic.get_policy_operator(), break_when_any_done=False)
    finally:
        env.close()
    trunk = trunk_of(actor_critic)
    points = td.get(POINTS_KEY, None) if isinstance(trunk.encoder, PointNetEncoder) else None
    trunk.set_normalization(td[STATE_KEY], points)


class DetachedInput(torch.nn.Module):
    """``net`` applied to a detached input: its own parameters learn, nothing upstream does."""

    def __init__(self, net: torch.nn.Module):
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x.detach())


def bc_warmstart(actor_critic, samples, epochs: int, seed: int, lr: float = 1e-3, batch: int = 256,
                 renormalize: bool = True) -> list[float]:
    """Fix the trunk's input normalisation from ``samples`` (the demonstrations; unless ``renormalize`` is
    False), then ``epochs`` passes of Adam on the MSE of the action mean to ``samples["expert_action"]``;
    the mean loss of each epoch."""
    if renormalize:
        trunk_of(actor_critic).set_normalization(samples[STATE_KEY], samples.get(POINTS_KEY, None))
    policy = actor_critic.get_policy_operator()
    params = [p for p in policy.parameters() if p.requires_grad]
    optimizer = torch.optim.Adam(params, lr=lr)
    generator, losses = torch.Generator().manual_seed(seed), []
    for _ in range(epochs):
        total = 0.0
        for idx in torch.randperm(len(samples), generator=generator).split(batch):
            loc, _ = action_distribution(policy, samples[idx])
            loss = torch.nn.functional.mse_loss(loc, samples[idx]["expert_action"])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            total += float(loss.detach()) * len(idx)
        losses.append(total / len(samples))
    return losses


def clone_the_guide(cfg: PPOConfig, actor_critic) -> tuple:
    """(samples, info): the guide's demonstrations (``--demo-episodes``), the actor cloned on them
    (``--bc-warmstart``) and ``--dagger-rounds`` in which the clone drives and the guide labels. A resumed run
    collects the demonstrations again (same seeds, same data) for the BC term, but neither clones nor runs
    the DAgger rounds again (its weights come from the checkpoint). With ``--init-from`` nothing is cloned:
    the loaded policy drives the DAgger rounds unchanged, so a resumed run (which loads it before the
    checkpoint) collects the same data again."""
    kwargs = {k: v for k, v in cfg.env_kwargs().items() if k != "max_episode_steps"}
    samples, guide_success = guide_demos(cfg.task, cfg.split, cfg.demo_episodes, cfg.demo_noise, 10_000 + cfg.seed,
                                         kwargs, cfg.guide)
    # an --init-from policy keeps its own input normalisation (the one it was trained with)
    warm = bc_warmstart(actor_critic, samples, cfg.bc_warmstart, cfg.seed,
                        renormalize=not cfg.init_from) if not cfg.resume else []
    info = {"guide_success": guide_success, "warmstart_loss": warm, "dagger_success": []}
    for r in range(cfg.dagger_rounds if cfg.init_from or not cfg.resume else 0):  # the student drives, the guide labels
        visited, success = guide_demos(cfg.task, cfg.split, cfg.demo_episodes, 0.0, 20_000 + 1000 * r + cfg.seed,
                                       kwargs, cfg.guide, driver=policy_function(actor_critic))
        samples = torch.cat([samples, visited])
        info["dagger_success"].append(success)  # the student's own success in this round
        info["warmstart_loss"] += bc_warmstart(actor_critic, samples, cfg.bc_warmstart, cfg.seed + 1 + r,
                                               renormalize=False)
    return samples, {"frames": len(samples), **info}


def build_learner(cfg: PPOConfig, env_fn) -> Learner:
    """Actor-critic (from scratch, from ``--init-from``, or with a pretrained and optionally frozen PointNet),
    ClipPPOLoss, Adam and GAE."""
    from torchrl.modules import ValueOperator
    from torchrl.objectives import ClipPPOLoss
    from torchrl.objectives.value import GAE

    probe = env_fn()
    num_points, state_dim, action_dim = env_dims(probe)
    probe.close()
    arch, weights = initial_weights(cfg, state_dim, action_dim)
    if (cfg.obs_norm_steps or cfg.demo_episodes) and weights is None:
        arch["normalize"] = True
    actor_critic = make_actor_critic(state_dim, action_dim, network_encoder(asdict(cfg)), cfg.init_log_std, **arch)
    if cfg.obs_norm_steps and not cfg.resume:  # a resumed run loads the statistics with the weights
        init_normalization(actor_critic, env_fn, cfg.obs_norm_steps, cfg.seed)
    if weights is not None:  # strict: every weight of the student, the input normalisation included
        actor_critic.load_state_dict(weights, strict=True)
        set_action_log_std(actor_critic, cfg.init_log_std)  # the student's log-std was never trained (MSE)
    bc_data, demo_info = load_demos(cfg.bc_demos) if cfg.bc_coef > 0 and cfg.bc_demos else None, None
    if cfg.demo_episodes:  # after --init-from: its policy drives the DAgger rounds
        bc_data, demo_info = clone_the_guide(cfg, actor_critic)
    if cfg.pretrained:
        load_encoder(cfg.pretrained, encoder_of(actor_critic), strict=True)
    if cfg.freeze_encoder:
        encoder_of(actor_critic).requires_grad_(False)
    # the critic is the value HEAD, so the trunk runs once per minibatch (it reads the actor's "hidden")
    critic = actor_critic.get_value_head()
    if cfg.critic_detach:  # same value MLP and weights, fed a detached copy of the trunk's features
        critic = ValueOperator(DetachedInput(critic.module), in_keys=list(critic.in_keys))
    loss_module = ClipPPOLoss(actor_network=actor_critic.get_policy_operator(),
                              critic_network=critic, clip_epsilon=cfg.clip_epsilon,
                              entropy_coeff=cfg.entropy_coef, critic_coeff=cfg.vf_coef, loss_critic_type="l2",
                              normalize_advantage=cfg.normalize_advantage)
    trainable = [p for p in loss_module.parameters() if p.requires_grad]
    value_head = set(actor_critic.get_value_head().parameters())
    groups = [{"params": [p for p in trainable if p not in value_head]},
              {"params": [p for p in trainable if p in value_head], "lr": cfg.critic_lr or cfg.lr}]
    optimizer = torch.optim.Adam(groups, lr=cfg.lr, eps=cfg.adam_eps)
    gae = GAE(gamma=cfg.gamma, lmbda=cfg.lmbda, value_network=None, average_gae=False)  # reads the values
    dims = {"num_points": num_points, "state_dim": state_dim, "action_dim": action_dim,
            **{k: list(v) if isinstance(v, tuple) else v for k, v in architecture(arch).items()}}
    anchor = None
    if cfg.anchor_coef > 0:  # the student as loaded, before any update (a resumed run reloads it from --init-from)
        anchor = copy.deepcopy(actor_critic.get_policy_operator()).requires_grad_(False)
    sil = SelfImitationBuffer(cfg.sil_capacity, cfg.gamma) if cfg.sil_coef > 0 else None
    return Learner(actor_critic, loss_module, optimizer, trainable, gae, actor_critic.get_value_operator(), dims,
                   bc_data, anchor, sil, critic, demo_info)


def restore(learner: Learner, cfg: PPOConfig, path: Path, curriculum: Curriculum | None = None) -> tuple[int, int, list]:
    """Weights, optimizer and curriculum from a checkpoint of the same task and encoder; (frames, batches, history)."""
    state = load_checkpoint(path)
    if curriculum is not None:
        if state.get("curriculum") is None:
            raise ValueError(f"--resume: {path} was trained without a curriculum; resume it with --curriculum none")
        curriculum.load_state_dict(state["curriculum"])
    if state["config"]["encoder"] != cfg.encoder or state["config"]["task"] != cfg.task:
        raise ValueError(f"--resume: {path} is a {state['config']['encoder']} {state['config']['task']} "
                         f"run, not {cfg.encoder} {cfg.task}")
    try:
        learner.actor_critic.load_state_dict(state["model"], strict=True)
    except RuntimeError:
        raise ValueError(f"--resume: {path} holds a network of another shape (its architecture: "
                         f"{architecture(state['dims'])}); resume with the same --head / --state-hidden") from None
    learner.optimizer.load_state_dict(state["optimizer"])
    if learner.demos is not None and state.get("demos"):  # what the first invocation measured of the warm start
        # "frames": the demonstration steps the run took (its DAgger rounds included); a resumed run's BC term
        # replays only the re-collected demonstrations ("bc_samples")
        learner.demos["bc_samples"] = learner.demos["frames"]
        learner.demos.update(state["demos"])
    return state["frames"], state["batches"], state["history"]


def save(learner: Learner, cfg: PPOConfig, path: Path, frames: int, batches: int, history: list,
         curriculum: Curriculum | None = None) -> Path:
    """The run's state: weights, optimizer, counters, history and the curriculum's schedule (frontiers,
    streaks). Not kept: the workers' env and RNG states (a resumed run collects on new seeds) and the
    self-imitation buffer."""
    return save_checkpoint(path, {
        "config": asdict(cfg), "model": to_cpu(learner.actor_critic.state_dict()),
        "optimizer": to_cpu(learner.optimizer.state_dict()),
        "frames": frames, "batches": batches, "history": history, "dims": learner.dims,
        "curriculum": curriculum.state_dict() if curriculum is not None else None, "demos": learner.demos})


def advantages(data, learner: Learner, reward_scale: float = 1.0):
    """GAE over time (the last batch dimension), once per batch as SB3, on the rewards times
    ``reward_scale``; the flat batch the loss reads."""
    with torch.no_grad():
        if reward_scale != 1.0:
            data["next", "reward"] = data["next", "reward"] * reward_scale
        add_next_values(data, learner.value_operator)
        learner.gae(data)
    return data.reshape(-1).select(*BATCH_KEYS, strict=False)


def bc_weight(cfg: PPOConfig, batch: int) -> float:
    """Weight of the BC term in batch ``batch`` (0-based): ``bc_coef``, times ``bc_decay`` per batch after
    the critic warm-up (during the warm-up the actor does not learn at all)."""
    if cfg.bc_coef == 0 or batch < cfg.critic_warmup:
        return 0.0
    return cfg.bc_coef * cfg.bc_decay ** (batch - cfg.critic_warmup)


def anchor_weight(cfg: PPOConfig, batch: int) -> float:
    """Weight of the KL anchor in batch ``batch`` (0-based): ``anchor_coef``, times ``anchor_decay`` per batch
    after the critic warm-up (none during it: the actor does not learn then), never below ``anchor_floor``."""
    if cfg.anchor_coef == 0 or batch < cfg.critic_warmup:
        return 0.0
    return max(cfg.anchor_coef * cfg.anchor_decay ** (batch - cfg.critic_warmup), cfg.anchor_floor)


def action_distribution(policy, samples) -> tuple[torch.Tensor, torch.Tensor]:
    """(loc, scale), each (N, action_dim), of the Gaussian that ``policy`` (a policy operator) puts on the
    point clouds and state vectors of ``samples``."""
    td = policy(samples.select(POINTS_KEY, STATE_KEY, strict=False).clone())
    return td["loc"], td["scale"]


def bc_loss(learner: Learner, size: int, generator: torch.Generator) -> torch.Tensor:
    """MSE of the policy's action mean to the expert labels, on ``size`` random demonstration samples."""
    idx = torch.randint(len(learner.bc_data), (size,), generator=generator)
    samples = learner.bc_data[idx].to(learner.device)
    loc, _ = action_distribution(learner.actor_critic.get_policy_operator(), samples)
    return torch.nn.functional.mse_loss(loc, samples["expert_action"])


def add_anchor(flat, learner: Learner, chunk: int = 1000) -> None:
    """``flat["anchor_loc"]`` and ``flat["anchor_scale"]``, (N, action_dim): the initial policy's action
    distribution on the batch's states, computed once per batch without gradients."""
    with torch.no_grad():
        parts = [action_distribution(learner.anchor, flat[i:i + chunk]) for i in range(0, flat.numel(), chunk)]
    flat["anchor_loc"], flat["anchor_scale"] = (torch.cat(part) for part in zip(*parts))


def anchor_kl(learner: Learner, samples) -> torch.Tensor:
    """Mean over ``samples`` of KL(pi(.|s) || pi_init(.|s)) for diagonal Gaussians, summed over the action
    dimensions (nats); the current policy is evaluated again here (its trunk included)."""
    loc, scale = action_distribution(learner.actor_critic.get_policy_operator(), samples)
    loc0, scale0 = samples["anchor_loc"], samples["anchor_scale"]
    kl = torch.log(scale0 / scale) + (scale ** 2 + (loc - loc0) ** 2) / (2 * scale0 ** 2) - 0.5
    return kl.sum(-1).mean()


def ppo_update(flat, learner: Learner, cfg: PPOConfig, batch: int = 0) -> dict:
    """``cfg.epochs`` passes of clipped-PPO minibatch steps over one batch; the mean of each loss term.

    ``batch`` (0-based) < ``cfg.critic_warmup``: only the value loss, and only the value head steps (the
    trunk is shared, so the actor stays exactly as it was). With ``bc_coef`` the BC term (``bc_weight``)
    is added to every minibatch's loss, with ``anchor_coef`` the KL to the initial policy (``anchor_kl``),
    and with ``sil_coef`` the self-imitation loss on as many steps of the best episodes (``rl/sil.py``)."""
    warmup, bc, anchor = batch < cfg.critic_warmup, bc_weight(cfg, batch), anchor_weight(cfg, batch)
    anchored = learner.anchor is not None and not warmup
    if anchored:
        add_anchor(flat, learner)
    value_head = set(learner.actor_critic.get_value_head().parameters())
    generator = torch.Generator().manual_seed(cfg.seed * 100_003 + batch)
    sil = learner.sil if learner.sil is not None and len(learner.sil) and not warmup else None
    sums, steps = dict.fromkeys(LOSS_KEYS + ("loss_bc", "kl_init") + SIL_KEYS, 0.0), 0
    planned = cfg.epochs * math.ceil(flat.numel() / cfg.minibatch)
    for _ in range(cfg.epochs):
        for idx in torch.randperm(flat.numel()).split(cfg.minibatch):
            loss_td = learner.loss_module(flat[idx])
            # SB3's early stop: this minibatch already sees a policy too far from the collecting one. Not
            # before the first step: the policy is then the collecting one, and its KL is float32 noise
            # (measured 7.6e-8 between the collection's and the loss's log-probabilities).
            if (not warmup and steps > 0 and cfg.target_kl is not None
                    and float(loss_td["kl_approx"]) > 1.5 * cfg.target_kl):
                break
            if warmup:
                loss = loss_td["loss_critic"]
            else:
                loss = loss_td["loss_objective"] + loss_td["loss_critic"] + loss_td["loss_entropy"]
                if bc > 0:
                    loss_td["loss_bc"] = bc_loss(learner, len(idx), generator)
                    loss = loss + bc * loss_td["loss_bc"]
                if anchored:
                    loss_td["kl_init"] = anchor_kl(learner, flat[idx])
                    loss = loss + anchor * loss_td["kl_init"]
                if sil is not None:
                    term, parts = sil_loss(learner.actor_critic.get_policy_operator(), learner.critic,
                                           sil.sample(len(idx), generator).to(learner.device), cfg.sil_value_coef)
                    loss = loss + cfg.sil_coef * term
                    loss_td.update({k: torch.tensor(v) for k, v in parts.items()})  # floats -> the loss's 0-d tensors
            learner.optimizer.zero_grad()
            loss.backward()
            if warmup:  # Adam skips parameters without a gradient: the actor does not move at all
                for p in learner.trainable:
                    if p not in value_head:
                        p.grad = None
            torch.nn.utils.clip_grad_norm_(learner.trainable, cfg.max_grad_norm)
            learner.optimizer.step()
            for key in sums:
                sums[key] += float(loss_td[key].detach()) if key in loss_td.keys() else 0.0
            steps += 1
        else:
            continue
        break
    return {**{k: v / max(steps, 1) for k, v in sums.items()}, "critic_warmup": float(warmup), "bc_weight": bc,
            "anchor_weight": anchor, "update_steps_frac": steps / planned}


def progress_bar(cfg, initial: int) -> tqdm:
    """The run's frames bar (``cfg``: a PPOConfig or SACConfig); with a time budget the ETA is for all frames,
    the budget ends the run sooner."""
    algo = getattr(cfg, "algo", "ppo").upper()
    return tqdm(total=cfg.frames, initial=initial, unit="frame", unit_scale=True, dynamic_ncols=True,
                disable=not cfg.progress,
                desc=f"{algo} {cfg.task}" + (f" (stops after {cfg.max_minutes:g} min)" if cfg.max_minutes else ""))


def evaluate_and_report(cfg, policy, history: list, start: float) -> dict:
    """Evaluation of ``policy`` (the actor-critic, or an off-policy run's actor) on seen and unseen objects,
    learning curve, optional GIF and ``report.md``; ``cfg`` is the run's PPOConfig or SACConfig."""
    from dexart_lite.rl.evaluate import evaluate_splits, markdown_table, record_gif
    from dexart_lite.rl.report import network_label, plot_curve, write_report

    out, gif = Path(cfg.out), None
    evals = evaluate_splits(policy, cfg, out)
    if cfg.gif:
        name = objects_lib.list_objects(cfg.task, "seen")[0].name
        gif = record_gif(policy, cfg.task, out / "episode.gif", "seen", name, cfg.eval_seed,
                         cfg.env_kwargs())["path"]
    curve = plot_curve(history, out / "learning_curve.png",
                       title=f"{getattr(cfg, 'algo', 'ppo').upper()} {cfg.task}, {network_label(asdict(cfg))}")
    wall = time.perf_counter() - start
    report = write_report(out / "report.md", asdict(cfg), history, evals, curve, wall, gif)
    if evals and cfg.progress:
        print(markdown_table(evals))
    return {"report": str(report), "curve": str(curve), "gif": gif, "log_dir": str(out / "log"),
            "wall_time_s": wall, "eval": {e["split"]: e for e in evals}}


def warmstart_evaluation(cfg: PPOConfig, learner: Learner) -> dict:
    """Success of the cloned policy before any PPO update, as the final evaluation measures it (seen and unseen
    objects, from the true reset, deterministic): what the demonstrations alone give."""
    from dexart_lite.rl.evaluate import evaluate

    return {split: evaluate(learner.actor_critic, cfg.task, split, cfg.eval_episodes, cfg.eval_seed,
                            cfg.env_kwargs())["success_rate"] for split in ("seen", "unseen")}


def learn(data, learner: Learner, acting, cfg: PPOConfig, batch: int, device: torch.device) -> tuple:
    """One collected batch learnt from: advantages, the PPO update (on ``device``), the acting copy synced.
    Returns the batch on the CPU (its rewards scaled by ``cfg.reward_scale``) and the update's mean losses."""
    data = data.contiguous()  # the distributed collector yields a lazy stack of the workers' batches
    on_device = device.type != "cpu"
    data = data.to(device) if on_device else data
    flat = advantages(data, learner, cfg.reward_scale)  # the rewards in data are scaled from here on
    if learner.sil is not None:  # the batch's finished episodes join the best ones (before the update)
        learner.sil.add(data)
    losses = ppo_update(flat, learner, cfg, batch)
    learner.sync_acting(acting)
    return (data.cpu() if on_device else data), losses  # the log and the curriculum read it on the CPU


def learner_stats(learner: Learner) -> dict:
    """The policy's mean log std and, with self-imitation, the size and best return of its buffer."""
    return {"log_std": float(action_log_std(learner.actor_critic).mean()),
            **({"sil_steps": len(learner.sil), "sil_best_return": learner.sil.best_return()}
               if learner.sil is not None else {})}


def train(cfg: PPOConfig) -> dict:
    """Train, evaluate on seen and unseen objects, write the report; returns the paths and results."""
    from torchrl.record.loggers import CSVLogger

    start = time.perf_counter()
    out = open_run(cfg)
    ckpt_path = out / CHECKPOINT
    learner_threads = cfg.threads or torch.get_num_threads()
    torch.set_num_threads(learner_threads)
    torch.manual_seed(cfg.seed)

    # ---- env factory (picklable, for the worker processes), the learner, and where we start from
    env_fn = partial(make_env, cfg.task, split=cfg.split, **cfg.env_kwargs())
    learner = build_learner(cfg, env_fn)
    curriculum = make_curriculum(cfg)  # the start-state schedule (None: true resets only); its state lives here
    frames_done, batches, history = restore(learner, cfg, ckpt_path, curriculum) if cfg.resume else (0, 0, [])
    if learner.demos is not None and (cfg.bc_warmstart or cfg.init_from) and not cfg.resume and cfg.eval_episodes:
        learner.demos["warmstart_eval"] = warmstart_evaluation(cfg, learner)  # the curve's frame 0
    device = resolve_device(cfg.device, log=tqdm.write)
    acting = learner.to(device)  # collection and evaluation act on the CPU (a copy when learning on cuda)

    # ---- collection: the collector runs the whole actor-critic (action + value in one trunk pass, ``Acting``).
    # Worker i seeds its env with its own seed (a new stream after --resume); the factories seed
    # the envs because DistributedCollector.set_seed fails in torchrl 0.14.1.
    collector = None
    if cfg.frames > frames_done:
        level = dict(level=curriculum.level(), guide=cfg.guide, guide_render=cfg.guide_render) if curriculum else {}
        env_fns = [partial(env_fn, seed=cfg.seed + 1000 * batches + i, **level) for i in range(max(cfg.workers, 1))]
        collector = make_collector(cfg, env_fns, acting, total_frames=cfg.frames - frames_done)
    in_process = cfg.backend == "process" and cfg.workers <= 1  # collects in this process, one action at a time
    collect_threads = 1 if in_process else learner_threads
    logger, bar = CSVLogger(exp_name="log", log_dir=str(out)), progress_bar(cfg, frames_done)
    tick = time.perf_counter()
    try:  # shut the workers down on errors too
        torch.set_num_threads(collect_threads)
        for data in (collector if collector is not None else []):  # not `or []`: RayCollector breaks bool()
            collected = time.perf_counter()
            torch.set_num_threads(learner_threads)
            data, losses = learn(data, learner, acting, cfg, batches, device)
            collector.update_policy_weights_()
            starts = curriculum.update(data) if curriculum is not None else {}  # frontiers move on this batch
            if cfg.curriculum == "reverse":
                send_level(collector, curriculum.level())
            if cfg.trim_memory:
                release_freed_memory()  # the update's freed activations back to the OS (see utils)
            updated = time.perf_counter()

            # ---- logging and checkpoints
            n = data.numel()
            frames_done, batches = frames_done + n, batches + 1
            row = {"frames": frames_done, "batch": batches, **batch_stats(data), **starts, **losses,
                   **value_error_at_start(data, cfg.gamma), **learner_stats(learner),
                   "collect_s": collected - tick, "update_s": updated - collected,
                   "collect_fps": n / (collected - tick), "update_fps": n / (updated - collected),
                   "fps": n / (updated - tick), "rss_mb": resident_mb(), "wall_s": time.perf_counter() - start}
            history.append(row)
            logger.log_metrics({k: v for k, v in row.items() if not math.isnan(v)}, step=frames_done)
            bar.update(n)
            bar.set_postfix(ret=f"{row['episode_return']:.1f}", succ=f"{row['success_rate']:.2f}", fps=f"{row['fps']:.0f}")
            if batches % cfg.checkpoint_every == 0:
                save(learner, cfg, ckpt_path, frames_done, batches, history, curriculum)
            if cfg.max_minutes is not None and time.perf_counter() - start > 60 * cfg.max_minutes:
                break
            torch.set_num_threads(collect_threads)
            tick = time.perf_counter()
    finally:
        bar.close()
        if collector is not None:
            collector.shutdown()
        torch.set_num_threads(learner_threads)
    ckpt = save(learner, cfg, ckpt_path, frames_done, batches, history, curriculum)
    result = evaluate_and_report(cfg, acting, history, start)  # ---- seen and unseen objects, curve, report
    return {"checkpoint": str(ckpt), "frames": frames_done, "history": history, "demos": learner.demos,
            "device": device.type, **result}


# ---------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from dexart_lite.cli import add_config_arguments

    parser.add_argument("--preset", default="faithful", help=f"starting point: {', '.join(PRESETS)}")
    # defaults None: the preset supplies every field not given on the command line
    add_config_arguments(parser, PPOConfig, given_only=True, default_label="faithful preset")


def config_from_args(args: argparse.Namespace) -> PPOConfig:
    """The preset named by ``--preset`` with every option given on the command line (flags, ``--set``) applied."""
    from dexart_lite.cli import config_from_args as from_args

    return from_args(PPOConfig, args, lambda **given: preset(args.preset, **given))
