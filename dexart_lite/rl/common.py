"""What the two learners (``rl/ppo.py``, ``rl/sac.py``) share: the checkpoint's file name, the network widths
and env keywords of a config, the start-state curriculum, the per-batch log statistics, the progress bar, and
the final evaluation with its report.

``cfg`` below is a ``PPOConfig`` or a ``SACConfig``: both have the fields read here, with the same meaning.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict
from pathlib import Path

import torch
from tqdm import tqdm

from dexart_lite import objects as objects_lib
from dexart_lite.rl.curriculum import Curriculum, CurriculumConfig, find_demos
from dexart_lite.rl.learners import learner_name

CHECKPOINT = "checkpoint.pt"  # in the run's --out folder


def head_widths(head: str) -> tuple[int, ...]:
    """``--head`` ("64,64") as integers; a ValueError names the expected form."""
    try:
        widths = tuple(int(w) for w in head.split(","))
    except ValueError:
        widths = ()
    if not widths or min(widths) < 1:
        raise ValueError(f"--head must be comma-separated positive widths such as 64,64, not {head!r}")
    return widths


def env_kwargs(cfg) -> dict:
    """Keyword arguments of the env that the training, evaluation and GIF envs share (DexArt's values left out)."""
    kwargs = {"num_points": cfg.num_points}
    if cfg.reward != "dexart":
        kwargs["reward"] = cfg.reward
    if cfg.obs != "cloud":
        kwargs["observation"] = cfg.obs
    if cfg.hand != "joints":
        kwargs["hand"] = cfg.hand
    if cfg.max_episode_steps:
        kwargs["max_episode_steps"] = cfg.max_episode_steps
    return kwargs


# ---------------------------------------------------------------- start-state curriculum
def curriculum_config(cfg) -> CurriculumConfig:
    return CurriculumConfig(cfg.curriculum, cfg.curriculum_horizon, cfg.curriculum_demos, cfg.curriculum_step,
                            cfg.curriculum_successes, cfg.curriculum_backoff, cfg.curriculum_true_resets,
                            probe=cfg.curriculum_probe, guide=cfg.guide)


def make_curriculum(cfg) -> Curriculum | None:
    """The run's start-state schedule (None without one); ``reverse`` first finds its demonstrations: the
    guide's solved episodes on the training objects (seeds from ``cfg.seed``)."""
    if cfg.curriculum == "none":
        return None
    ccfg = curriculum_config(cfg)
    kwargs = {k: v for k, v in cfg.env_kwargs().items() if k != "observation"}
    demos = find_demos(cfg.task, ccfg.demos, cfg.split, cfg.seed, kwargs, cfg.guide) if ccfg.schedule == "reverse" else None
    return Curriculum(ccfg, demos)


# ---------------------------------------------------------------- what a batch's log row says
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


# ---------------------------------------------------------------- progress, evaluation and report
def progress_bar(cfg, initial: int) -> tqdm:
    """The run's frames bar; with a time budget the ETA is for all frames, the budget ends the run sooner."""
    return tqdm(total=cfg.frames, initial=initial, unit="frame", unit_scale=True, dynamic_ncols=True,
                disable=not cfg.progress,
                desc=f"{learner_name(cfg).upper()} {cfg.task}"
                     + (f" (stops after {cfg.max_minutes:g} min)" if cfg.max_minutes else ""))


def evaluate_and_report(cfg, policy, history: list, start: float) -> dict:
    """Evaluation of ``policy`` (the actor-critic, or an off-policy run's actor) on seen and unseen objects,
    learning curve, optional GIF and ``report.md``."""
    from dexart_lite.rl.evaluate import evaluate_splits, markdown_table, record_gif
    from dexart_lite.rl.report import network_label, plot_curve, write_report

    out, gif = Path(cfg.out), None
    evals = evaluate_splits(policy, cfg, out)
    if cfg.gif:
        name = objects_lib.list_objects(cfg.task, "seen")[0].name
        gif = record_gif(policy, cfg.task, out / "episode.gif", "seen", name, cfg.eval_seed,
                         cfg.env_kwargs())["path"]
    curve = plot_curve(history, out / "learning_curve.png",
                       title=f"{learner_name(cfg).upper()} {cfg.task}, {network_label(asdict(cfg))}")
    wall = time.perf_counter() - start
    report = write_report(out / "report.md", asdict(cfg), history, evals, curve, wall, gif)
    if evals and cfg.progress:
        print(markdown_table(evals))
    return {"report": str(report), "curve": str(curve), "gif": gif, "log_dir": str(out / "log"),
            "wall_time_s": wall, "eval": {e["split"]: e for e in evals}}
