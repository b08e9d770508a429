"""Start-state curricula: the learner's episode begins where a guide (the scripted expert) has already been.

At a reset a *guide* acts ``h`` steps in the env and the learner's episode begins in the state it left;
the guide's steps never reach the learner's data (they happen inside ``GuidedStart.reset``), so every
collected frame, and every frame counted, is the learner's. With ``h = 0`` the reset is the env's own.
The guide is the task's scripted expert (privileged: it reads the simulator) or a trained checkpoint;
either way it is used in training only, and the policy's observation is unchanged.

Schedules (``SCHEDULES``):

* ``none``: the env's own resets (DexArt).
* ``uniform``: ``h ~ U[0, H]`` on a fresh reset seed (JSRL-Random, Uchendu et al. 2023).
* ``reverse``: reverse forward curriculum (RFCL, Tao et al. 2024). ``demos`` demonstrations, each a
  ``(reset seed, object)`` pair on which the guide succeeds at step ``L``, keep a start *frontier*,
  first ``L - 1`` (one step before the guide's success). Starts are drawn at ``frontier + k`` with
  ``k`` = 0..4 at probabilities 1/2, 1/4, 1/8, 1/16, 1/16; after ``successes`` successes in a row from
  exactly the frontier it moves back by ``step`` (never below 0). With ``backoff`` > 0 it also moves *forward*
  by ``step`` (never past ``L - 1``) after ``backoff`` failures in a row from it, so that a frontier the
  learner can no longer finish from comes back to starts it can (Florensa et al. 2017 keep the starts at
  0.1-0.9 success); 0 (RFCL): frontiers only move back. With ``probe`` > 0 that share of the guided
  episodes instead starts at ``h ~ U{0, ..., frontier - 1}`` of its demonstration, and a success from such an
  earlier start moves the frontier back to it at once: on a demonstration whose difficulty is not monotone in
  ``h`` (the learner fails from the guide's late states and succeeds from earlier ones) RFCL's rule never moves
  the frontier, and backoff cannot (it stops at ``L - 1``); 0 (RFCL): no probes. A fraction ``true_resets`` of the
  episodes start from the true reset, and once 90 % of the frontiers have reached 0 every episode does.

Where the state lives: the schedule (``Curriculum``: frontiers, streaks, counts) lives in the trainer and
is saved in its checkpoint; the workers' wrappers hold only a copy of its ``level()`` (a plain dict), set
with gymnasium's ``set_wrapper_attr`` (``send_level``) after every batch. A worker reports each
episode's start in its info (``start_step``, ``start_demo``), so the trainer reads from the batch which
episodes started where and whether they succeeded (``Curriculum.update``).

    env = GuidedStart(gym.make("DexArtLite/Laptop-v0"), level={"schedule": "uniform", "horizon": 130})
    obs, info = env.reset(seed=0)     # info["start_step"]: the guide's steps before this observation
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import torch

from dexart_lite.utils import check_choice, fast_mode

SCHEDULES = ("none", "uniform", "reverse")
LEVEL_ATTR = "curriculum_level"  # the wrapper attribute the trainer sets on every worker
# RFCL's start offsets past the frontier and their probabilities (rfcl/envs/wrappers/curriculum.py)
OFFSET_PROBS = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625])
DONE_FRACTION = 0.9  # reverse: once this share of frontiers is at 0, every episode starts from the true reset


def check_guide(guide: str) -> None:
    """``guide`` is ``"expert"`` or the path of a checkpoint file (a PPO or distill run of the task)."""
    from dexart_lite.rl.checkpoint import checkpoint_path

    if guide != "expert" and not checkpoint_path(guide).is_file():
        raise ValueError(f"unknown guide {guide!r}: valid choices are 'expert', zoo:<task> or the path of a "
                         f"checkpoint file")


def make_guide(env: gym.Env, guide: str):
    """``obs -> action`` of the guide acting in ``env``: the task's scripted expert or a checkpoint's
    deterministic policy."""
    check_guide(guide)
    if guide == "expert":
        from dexart_lite.experts import ScriptedPolicy, SynergyScriptedPolicy

        return (SynergyScriptedPolicy if env.unwrapped.hand_mode == "synergy" else ScriptedPolicy)(env)
    from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint, policy_function

    return policy_function(actor_critic_from_checkpoint(load_checkpoint(guide), guide))


class GuidedStart(gym.Wrapper):
    """A gymnasium env whose resets hand over after ``h`` guide steps; ``h`` follows ``curriculum_level``.

    ``level`` (``Curriculum.level()``): ``{"schedule": "none"}``, ``{"schedule": "uniform", "horizon": H}``
    or ``{"schedule": "reverse", "demos": [(seed, object, L), ...], "frontiers": [...], "true_resets": p,
    "probe": q}`` (``probe`` may be absent: 0).
    ``guide_render``: False skips the camera render on every guide step but the last (the physical state
    is the same; the point cloud's random draws then differ from a plain run's, which renders every step);
    a checkpoint guide, which acts on its observations, always renders.
    The wrapper draws its episode seeds and starts from its own generator, seeded by ``reset(seed=...)``.
    """

    def __init__(self, env: gym.Env, level: dict | None = None, guide: str = "expert", guide_render: bool = True):
        super().__init__(env)
        check_guide(guide)
        self.curriculum_level = level or {"schedule": "none"}
        self.guide_name, self.guide_render = guide, guide_render
        self._guide = None  # built on first use (the scripted expert reads the env's objects)
        self._rng = np.random.default_rng()
        self.guide_steps = 0  # guide steps taken so far (not the learner's frames)
        self._start = (0, -1)  # (h, demo index or -1) of the current episode

    @property
    def guide(self):
        """The guide policy (``obs -> action``) that led the current episode; None before its first step."""
        return self._guide

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        level = self.curriculum_level
        check_choice("schedule", level.get("schedule"), SCHEDULES)
        if level["schedule"] == "none":  # exactly the env
            return self._tagged(*self.env.reset(seed=seed, options=options), 0, -1)
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        episode_seed, name, h, demo = self._draw(level)
        if options and "object" in options:  # an explicit object wins over the schedule's
            name, demo = options["object"], -1
        return self.start(episode_seed, h, name, demo)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info["start_step"], info["start_demo"] = self._start
        return obs, reward, terminated, truncated, info

    # ------------------------------------------------------------------ the start
    def _draw(self, level: dict) -> tuple[int, str | None, int, int]:
        """(episode seed, object or None, h, demo index or -1) of the next episode."""
        rng = self._rng
        if level["schedule"] == "uniform":
            return int(rng.integers(2**31)), None, int(rng.integers(level["horizon"] + 1)), -1
        frontiers = np.asarray(level["frontiers"])
        if rng.random() < level["true_resets"] or np.mean(frontiers == 0) >= DONE_FRACTION:
            return int(rng.integers(2**31)), None, 0, -1
        weights = frontiers + 1.0  # RFCL: demos further from done are drawn more often
        demo = int(rng.choice(len(frontiers), p=weights / weights.sum()))
        seed, name, length = level["demos"][demo]
        # a probe: a start anywhere before the frontier (no draw at all without probes: RFCL's stream is unchanged)
        if level.get("probe", 0.0) > 0 and frontiers[demo] > 0 and rng.random() < level["probe"]:
            return int(seed), name, int(rng.integers(frontiers[demo])), demo
        h = min(int(frontiers[demo]) + int(rng.choice(len(OFFSET_PROBS), p=OFFSET_PROBS)), length - 1)
        return int(seed), name, h, demo

    def start(self, seed: int, h: int, name: str | None = None, demo: int = -1):
        """``(obs, info)`` of the state the guide leaves after ``h`` steps from ``reset(seed)`` (on object
        ``name`` if given); ``h = 0`` is that reset itself. A guide episode that ends first (success
        terminates it) is replayed to one step before its end, and ``info["start_step"]`` says so."""
        options = {"object": name} if name else None
        obs, info = self.env.reset(seed=seed, options=options)
        if self._guide is None and h > 0:
            self._guide = make_guide(self.env, self.guide_name)
        for t in range(h):
            self._render(t == h - 1)
            obs, _, terminated, truncated, info = self.env.step(self._guide(obs))
            self.guide_steps += 1
            if terminated or truncated:  # replay the same episode to its step t (the guide ended at t + 1)
                self._render(True)
                return self.start(seed, t, name, demo)
        self._render(True)
        return self._tagged(obs, info, h, demo)

    def _render(self, on: bool) -> None:
        # a checkpoint guide acts on what it observes: only the scripted expert (reading the simulator) can skip
        self.env.unwrapped.observe_steps = on or self.guide_render or self.guide_name != "expert"

    def _tagged(self, obs, info, h: int, demo: int):
        self._start = (h, demo)
        info["start_step"], info["start_demo"] = h, demo
        return obs, info


def find_demos(task: str, count: int, split: str = "seen", seed: int = 0, env_kwargs: dict | None = None,
               guide: str = "expert", max_tries: int = 4) -> list[tuple[int, str, int]]:
    """``count`` demonstrations of the guide, ``[(reset seed, object, L)]``: episodes on which it first succeeds
    at step ``L`` (faucet, laptop, toilet: the success ends the episode; bucket: it goes on to the horizon, and a
    frontier at the horizon would start the learner after the lift). Objects in turn (the ``solve`` order: episode ``k``
    of object ``i`` has seed ``seed + 1000 k + i``); an episode the guide fails is skipped. Run on the
    state observation (no camera) and the task's full horizon: the physics, and so ``L``, does not depend on
    what is observed."""
    from dexart_lite.envs import make
    from dexart_lite.experts.solve import solve_episodes
    from dexart_lite.rollout import run_episodes

    # the full horizon (a short test horizon would cut the guide off before it succeeds)
    kwargs = {k: v for k, v in (env_kwargs or {}).items() if k != "max_episode_steps"}
    if guide == "expert":
        kwargs["observation"] = "state"
    env = make(task, split=split, **kwargs)
    names = env.unwrapped.objects.names  # the split's, or the env_kwargs' object_names
    policy = make_guide(env, guide)
    demos = []
    try:
        for episode in solve_episodes(names, max_tries * math.ceil(count / len(names)), seed):
            result, = run_episodes(policy, env, [episode])
            # L: its first success (the bucket's episode goes on after it)
            if result["success"] and result["success_step"] > 0:
                demos.append((*episode, result["success_step"]))
            if len(demos) == count:
                return demos
    finally:
        env.close()
    raise RuntimeError(f"the {guide} guide succeeded on only {len(demos)} of the {count} {task} demonstrations "
                       f"asked for in {max_tries * math.ceil(count / len(names)) * len(names)} episodes")


@dataclass
class CurriculumConfig:
    """The schedule's settings (``PPOConfig`` carries them as ``curriculum_*`` fields)."""

    schedule: str = "none"
    horizon: int = 130  # uniform: the largest h
    demos: int = 11  # reverse: demonstrations (one per seen object by default)
    step: int = 5  # reverse: steps the frontier moves back
    successes: int = 3  # reverse: successes in a row from the frontier before it moves
    backoff: int = 0  # reverse: failures in a row from the frontier before it moves forward (0: never, RFCL)
    true_resets: float = 0.1  # reverse: share of episodes from the true reset
    probe: float = 0.0  # reverse: share of guided episodes from a uniform start before the frontier (0: none, RFCL)
    guide: str = "expert"

    def validate(self) -> None:
        check_choice("curriculum schedule", self.schedule, SCHEDULES)
        check_guide(self.guide)
        if self.horizon < 0:
            raise ValueError(f"curriculum horizon H must be >= 0, got {self.horizon}")
        for name in ("demos", "step", "successes"):
            if getattr(self, name) < 1:
                raise ValueError(f"curriculum {name} must be >= 1, got {getattr(self, name)}")
        if self.backoff < 0:
            raise ValueError(f"curriculum backoff must be >= 0 (0: frontiers never move forward), got {self.backoff}")
        for name in ("true_resets", "probe"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"curriculum {name} is a fraction in [0, 1], got {getattr(self, name)}")


class Curriculum:
    """The schedule's state, kept by the trainer: frontiers, streaks and what the episodes did.

    ``level()`` is what the workers need; ``update(batch)`` reads a collected batch's finished episodes
    (``start_step``, ``start_demo``, ``episode_success`` at their last step) and moves the frontiers;
    ``state_dict()`` / ``load_state_dict()`` carry it across ``--resume``."""

    def __init__(self, cfg: CurriculumConfig, demos: list[tuple[int, str, int]] | None = None):
        cfg.validate()
        if cfg.schedule == "reverse" and not demos:
            raise ValueError("the reverse schedule needs demonstrations (find_demos)")
        self.cfg, self.demos = cfg, [tuple(d) for d in (demos or [])]
        self.frontiers = np.array([length - 1 for _, _, length in self.demos], dtype=np.int64)
        self.streaks = np.zeros(len(self.demos), dtype=np.int64)
        self.failures = np.zeros(len(self.demos), dtype=np.int64)  # failures in a row from the frontier (backoff)

    def level(self) -> dict:
        if self.cfg.schedule == "uniform":
            return {"schedule": "uniform", "horizon": self.cfg.horizon}
        if self.cfg.schedule == "reverse":
            return {"schedule": "reverse", "demos": self.demos, "frontiers": self.frontiers.tolist(),
                    "true_resets": self.cfg.true_resets, "probe": self.cfg.probe}
        return {"schedule": "none"}

    def update(self, data) -> dict:
        """Move the frontiers on the episodes that ended in ``data`` (a collector batch); statistics to log."""
        done = data["next", "done"].squeeze(-1)
        starts = data["next", "start_step"][done].tolist()
        demos = data["next", "start_demo"][done].tolist()
        success = data["next", "episode_success"][done].tolist()
        # episodes from exactly their demo's frontier (as it was when they started)
        at_frontier = [bool(d >= 0 and self.cfg.schedule == "reverse" and h == self.frontiers[d])
                       for h, d in zip(starts, demos)]
        # with probes: episodes of a demonstration that started before its frontier (as it is now)
        probes = [bool(self.cfg.probe and d >= 0 and h < self.frontiers[d]) for h, d in zip(starts, demos)]
        for h, demo, ok, counts in zip(starts, demos, success, at_frontier):
            # solvable from an earlier start (the frontier may have moved within this batch): the frontier goes there
            if self.cfg.probe and demo >= 0 and ok and h < self.frontiers[demo]:
                self.frontiers[demo], self.streaks[demo], self.failures[demo] = h, 0, 0
            if not counts:
                continue
            self.streaks[demo] = self.streaks[demo] + 1 if ok else 0
            self.failures[demo] = 0 if ok else self.failures[demo] + 1
            if self.streaks[demo] >= self.cfg.successes:
                self.frontiers[demo] = max(0, self.frontiers[demo] - self.cfg.step)
                self.streaks[demo] = 0
            elif self.cfg.backoff and self.failures[demo] >= self.cfg.backoff:
                self.frontiers[demo] = min(self.demos[demo][2] - 1, self.frontiers[demo] + self.cfg.step)
                self.failures[demo] = 0
        return self.stats(starts, success, at_frontier, probes)

    def stats(self, starts: list, success: list, at_frontier: list, probes: list | None = None) -> dict:
        """Mean h and the guide steps of the ended episodes, success of those that started at h = 0, and for
        ``reverse`` the frontiers and the success of the episodes that started at their frontier (with probes
        also of those that started before it)."""
        def rate(mask):
            chosen = [ok for ok, m in zip(success, mask) if m]
            return float(np.mean(chosen)) if chosen else math.nan

        row = {"start_mean": float(np.mean(starts)) if starts else math.nan, "guide_steps": int(sum(starts)),
               "success_h0": rate([h == 0 for h in starts]), "episodes_h0": int(sum(h == 0 for h in starts))}
        if self.cfg.schedule == "reverse":
            row.update({"frontier_mean": float(self.frontiers.mean()), "frontier_max": int(self.frontiers.max()),
                        "reversed_frac": float(np.mean(self.frontiers == 0)), "success_frontier": rate(at_frontier),
                        "episodes_frontier": int(sum(at_frontier))})
            if self.cfg.probe:
                row.update({"success_probe": rate(probes), "episodes_probe": int(sum(probes))})
        return row

    def state_dict(self) -> dict:
        return {"config": vars(self.cfg).copy(), "demos": self.demos, "frontiers": self.frontiers.tolist(),
                "streaks": self.streaks.tolist(), "failures": self.failures.tolist()}

    def load_state_dict(self, state: dict) -> None:
        # a checkpoint written before a setting existed ran with its default (backoff 0: no failure counts;
        # probe 0)
        config = {**vars(CurriculumConfig()), **state["config"]}
        if config != vars(self.cfg) or [tuple(d) for d in state["demos"]] != self.demos:
            raise ValueError(f"--resume: the checkpoint's curriculum {config} does not match this run's "
                             f"{vars(self.cfg)}")
        self.frontiers = np.array(state["frontiers"], dtype=np.int64)
        self.streaks = np.array(state["streaks"], dtype=np.int64)
        self.failures = np.array(state.get("failures", [0] * len(self.demos)), dtype=np.int64)


def send_level(collector, level: dict) -> None:
    """Hand ``level`` to the wrapper of every env of ``collector`` (a torchrl ``Collector`` or
    ``MultiSyncCollector``); each uses it from its next reset."""
    if hasattr(collector, "num_workers"):  # a MultiSyncCollector: one call per worker process
        collector.map_fn("env.set_wrapper_attr", list_of_args=[(LEVEL_ATTR, level)] * collector.num_workers)
    else:
        collector.env.set_wrapper_attr(LEVEL_ATTR, level)


def read_levels(collector) -> list[dict]:
    """Each worker's current level (for tests and logs)."""
    if hasattr(collector, "num_workers"):
        return collector.map_fn("env.get_wrapper_attr", list_of_args=[(LEVEL_ATTR,)] * collector.num_workers)
    return [collector.env.get_wrapper_attr(LEVEL_ATTR)]


class Driven:
    """DAgger's executed policy: ``driver``'s action is executed, ``guide``'s (called on every step, so a
    stateful expert follows the episode) is kept as ``label``."""

    def __init__(self, guide, driver):
        self.guide, self.driver, self.label = guide, driver, None

    def reset(self) -> None:
        if hasattr(self.guide, "reset"):
            self.guide.reset()

    def __call__(self, obs: dict) -> np.ndarray:
        self.label = np.asarray(self.guide(obs), dtype=np.float64)
        return self.driver(obs)


def guide_env_kwargs(env_kwargs: dict) -> dict:
    """The learner's env settings for the guide's demonstrations: without its ``max_episode_steps``, since the
    guide needs the env's whole horizon to succeed; a fast-mode smoke run (``DEXART_LITE_FAST=1``) keeps the
    learner's cap, as it caps everything else."""
    return {k: v for k, v in env_kwargs.items() if k != "max_episode_steps" or fast_mode()}


def guide_demos(task: str, split: str, episodes_per_object: int, noise: float, seed: int,
                env_kwargs: dict | None = None, guide: str = "expert", driver=None, transitions: bool = False):
    """Demonstrations of the guide in the learner's observation, in memory: a ``TensorDict`` of ``S`` steps
    with ``observation`` (S, D), ``point_cloud`` (S, N, 3) unless the observation is the state alone, and
    ``expert_action`` (S, A), the clean label. The executed action is the label plus Gaussian noise of std
    ``noise`` (clipped), so the labels also cover states just off the guide's path (DART). Episode ``k`` of
    object ``i`` is reset with seed ``seed + 1000 k + i`` (the ``solve`` order) and the noise has its own
    generator seeded with ``seed``: the same arguments give the same samples. ``driver`` (``obs -> action``, e.g.
    the student being trained): it acts instead and the guide only labels the states it visits (DAgger).
    ``transitions``: also what an off-policy learner replays, in torchrl's layout: ``action`` (the executed
    one), ``("next", "observation")`` [and ``("next", "point_cloud")``], ``("next", "reward")`` (S, 1),
    ``("next", "terminated")`` and ``("next", "done")`` (S, 1) bool (done on the last step of each episode)."""
    from tensordict import TensorDict

    from dexart_lite.envs import make
    from dexart_lite.experts.solve import solve_episodes
    from dexart_lite.rollout import noisy, run_episodes

    env = make(task, split=split, **{"point_noise": True, "camera_noise": True, **(env_kwargs or {})})
    names = env.unwrapped.objects.names  # the split's, or the env_kwargs' object_names
    policy = noisy(make_guide(env, guide), noise, np.random.default_rng(seed)) if driver is None else \
        Driven(make_guide(env, guide), driver)
    rows, steps = [], []  # (obs, label); (action, reward, next obs, terminated) when transitions are kept
    terminates = env.unwrapped.TERMINATE_ON_SUCCESS

    def on_step(obs, action, reward, next_obs, info, t):
        rows.append((obs, policy.label))
        if transitions:
            steps.append((action, reward, next_obs, bool(info["success"]) and terminates))

    try:
        episodes = run_episodes(policy, env, solve_episodes(names, episodes_per_object, seed), on_step=on_step)
    finally:
        env.close()

    def stack(observations, key):
        return np.stack([o[key] for o in observations]).astype(np.float32)

    data = {"observation": stack([o for o, _ in rows], "state"),
            "expert_action": np.stack([a for _, a in rows]).astype(np.float32)}
    if "point_cloud" in rows[0][0]:
        data["point_cloud"] = stack([o for o, _ in rows], "point_cloud")
    samples = TensorDict({k: torch.from_numpy(v) for k, v in data.items()}, batch_size=[len(rows)])
    if transitions:
        done = np.zeros((len(rows), 1), dtype=bool)
        done[np.cumsum([e["steps"] for e in episodes]) - 1] = True  # the last step of every episode
        samples["action"] = torch.from_numpy(np.stack([a for a, *_ in steps]).astype(np.float32))
        following = [n for *_, n, _ in steps]
        nxt = {"observation": torch.from_numpy(stack(following, "state")),
               "reward": torch.tensor([[r] for _, r, *_ in steps], dtype=torch.float32),
               "terminated": torch.tensor([[term] for *_, term in steps]), "done": torch.from_numpy(done)}
        if "point_cloud" in data:
            nxt["point_cloud"] = torch.from_numpy(stack(following, "point_cloud"))
        samples["next"] = TensorDict(nxt, batch_size=[len(rows)])
    return samples, float(np.mean([e["success"] for e in episodes]))


__all__ = ["Curriculum", "CurriculumConfig", "GuidedStart", "SCHEDULES", "find_demos", "guide_demos", "make_guide",
           "read_levels", "send_level"]
