"""``PPOConfig``: one PPO run's settings, its named ``PRESETS`` and ``validate``.

The defaults are DexArt's PPO settings (its training script plus SB3's PPO defaults): ``preset="faithful"``.
Every field is a ``dexart-lite train`` flag (``--frames-per-batch``); the presets change a few of them.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
from dataclasses import dataclass, field
from pathlib import Path

from dexart_lite import objects as objects_lib
from dexart_lite.envs.rewards import REWARD_MODES
from dexart_lite.models.pointnet import ENCODER_SIZES
from dexart_lite.registration import HAND_MODES, OBSERVATIONS, TASKS
from dexart_lite.rl import common
from dexart_lite.rl.checkpoint import checkpoint_path
from dexart_lite.utils import DEVICES, check_choice, resolve_device

BACKENDS = ("process", "distributed", "ray")


@dataclass
class PPOConfig:
    """One training run. Defaults = DexArt's PPO (its training script + SB3's PPO defaults)."""

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
    split: str = field(default="seen", metadata={"help": "training objects: seen, seen_half or seen_wide (seen + "
                       "the wide split's extra toilets)"})
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
        return common.head_widths(self.head)

    def env_kwargs(self) -> dict:
        """Keyword arguments of the env that the training, evaluation and GIF envs share."""
        return common.env_kwargs(self)


# Named presets: the fields they change, each with its reason. Timed in benchmarks/perf/bench_training.py.
PRESETS: dict[str, dict] = {
    "faithful": {},  # DexArt's settings: PPOConfig's defaults
    # the same algorithm on 2 cores
    "cpu": {"frames_per_batch": 4000,  # 2 workers x 2000 steps: an update every ~20 s instead of every ~3 min
            "epochs": 5},  # half the gradient steps per frame
    # from scratch on 2 cores: the cpu preset with departures from DexArt that help a small budget
    "fast": {"frames_per_batch": 4000, "epochs": 5,
             "lr": 3e-4,  # the state-only diagnostic's rate, not 1e-4
             "reward_scale": 0.01,  # the critic fits values of order 1 (the success bonus reaches ~300)
             "init_log_std": -1.2,  # action std 0.3, not 1: with std 1 even the expert's actions lift no lid
             "obs_norm_steps": 2000},  # fixed input normalisation from the initial policy (DexArt: raw inputs)
    # PPO from a distilled student (--init-from): the cpu preset with guards that keep the cloned policy
    "finetune": {"frames_per_batch": 4000, "epochs": 5,
                 "init_log_std": -2.3,  # action std 0.1, not 1: the student's actions are millimetre-precise
                 "lr": 3e-5,  # small steps away from the student
                 "critic_warmup": 5,  # the student's value head was never trained: it learns alone first
                 "critic_detach": True,  # a critic still wrong cannot reshape the features the actor relies on
                 "reward_scale": 0.01,  # the critic fits values of order 1 (the success bonus reaches ~300)
                 "critic_lr": 1e-3,  # the value head catches up faster than the actor moves
                 "target_kl": 0.01,  # SB3's early stop: no batch moves the policy far
                 "eval_episodes": 3},  # DexArt's evaluation episodes per object in its distillation benchmark
    # `make demo`: the cpu preset on Laptop, <= 10 minutes in all on 2 cores
    "demo": {"frames_per_batch": 4000, "epochs": 5, "task": "laptop", "frames": 200_000,
             "max_minutes": 6.0,  # the training's time budget; evaluation and GIF follow
             "eval_episodes": 2, "gif": True, "out": "demo_out"},
}


def preset(name: str, **overrides) -> PPOConfig:
    """``PPOConfig`` of a named preset, with ``overrides`` applied."""
    check_choice("preset", name, PRESETS)
    return dataclasses.replace(PPOConfig(), **{**PRESETS[name], **overrides})


def validate(cfg: PPOConfig) -> None:
    """Raise a one-line error for any setting that cannot run, before anything is built."""
    check_choice("task", cfg.task, TASKS)
    check_choice("encoder size", cfg.encoder, ENCODER_SIZES)
    check_choice("backend", cfg.backend, BACKENDS)
    check_choice("training split", cfg.split, objects_lib.TRAINING_SPLITS)
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
    common.curriculum_config(cfg).validate()
    if cfg.curriculum != "none" and cfg.backend != "process":
        raise ValueError(f"a curriculum needs the process backend (its level reaches the workers through the "
                         f"collector), got backend {cfg.backend!r}")
    if cfg.backend == "ray" and importlib.util.find_spec("ray") is None:
        raise RuntimeError("the ray backend needs Ray, an optional extra: pip install '.[distributed]' "
                           "(or pip install 'dexart_lite[distributed]')")
