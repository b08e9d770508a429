"""One episode loop for the gymnasium envs, shared by evaluation, GIF recording, expert demonstrations,
DAgger and scripts.

    episodes = [(seed, "laptop_11cbb00f39"), (seed + 1, "laptop_cfd3b8b3b2")]
    results = run_episodes(policy, env, episodes, on_step=recorder)
    per_object_summary(results)["success_rate"]

A policy is any callable ``obs -> action (22,)``; one that must know when an episode starts has a
``reset()`` method, called right after ``env.reset``. Each episode is reset with its own seed and,
if given, its object (``options={"object": name}``), so a list of episodes replays exactly. As in
DexArt's evaluation, an episode is a success if it succeeds at any step.
"""

from __future__ import annotations

import time
from typing import Callable

import numpy as np
from tqdm import tqdm

from dexart_lite.utils import check_choice

Policy = Callable[[dict], np.ndarray]  # gymnasium observation -> action (22,)
# on_step(obs, action, reward, next_obs, info, t): obs is the observation the action was chosen on,
# info the env's info after the step, t the step index (0 for the first action of an episode)
OnStep = Callable[[dict, np.ndarray, float, dict, dict, int], None]
# the action dimensions a ``Noisy`` policy perturbs: the 6-D palm twist comes first, the hand's targets after it
NOISE_PARTS = {"all": slice(None), "arm": slice(0, 6), "hand": slice(6, None)}


def run_episodes(policy: Policy, env, episodes: list[tuple[int, str | None]], on_step: OnStep | None = None,
                 progress: bool = False, desc: str | None = None,
                 on_reset: Callable[[dict, dict], None] | None = None) -> list[dict]:
    """Run one episode per ``(seed, object_name)`` pair (``object_name`` None: drawn by the seed;
    ``seed`` None: the env's RNG goes on from the previous reset instead of being seeded again).

    ``on_reset(obs, info)`` is called after each reset, ``on_step`` after each step (see ``OnStep``).
    Returns one dict per episode: object, seed, success (at any step), success_step (the number of steps
    after which it first succeeded: 0 at the reset, None if never; on tasks that do not end at a success,
    the bucket, it is earlier than ``steps``), max_stage (highest stage, 1..3, including the reset state),
    return, steps, stages (the stage after each step).
    """
    results = []
    for seed, name in tqdm(episodes, desc=desc, unit="episode", disable=not progress, dynamic_ncols=True):
        obs, info = env.reset(seed=None if seed is None else int(seed), options={"object": name} if name else None)
        if hasattr(policy, "reset"):
            policy.reset()
        if on_reset is not None:
            on_reset(obs, info)
        success_step = 0 if info["success"] else None  # steps taken at the first success (None: not yet)
        max_stage, total, stages = int(info["stage"]), 0.0, []
        done, t = False, 0
        while not done:
            action = policy(obs)
            next_obs, reward, terminated, truncated, info = env.step(action)
            if on_step is not None:
                on_step(obs, action, reward, next_obs, info, t)
            if success_step is None and info["success"]:
                success_step = t + 1
            stages.append(int(info["stage"]))
            max_stage = max(max_stage, stages[-1])
            total += float(reward)
            obs, done, t = next_obs, terminated or truncated, t + 1
        results.append({"object": info["object_name"], "seed": seed, "success": success_step is not None,
                        "success_step": success_step, "max_stage": max_stage, "return": total, "steps": t,
                        "stages": stages})
    return results


class Noisy:
    """``policy`` with Gaussian noise of std ``sigma`` added to its action, then clipped to [-1, 1].

    The action before the noise stays readable as ``label`` (the clean expert action of a
    demonstration). ``rng`` is a ``numpy.random.Generator``, separate from the env's. ``part``
    (``NOISE_PARTS``) perturbs only the palm twist (``arm``) or only the hand (``hand``); the other
    dimensions are the policy's own (a full vector is still drawn, so the same ``rng`` seed gives the same
    draws on the dimensions both parts share with ``all``).
    """

    def __init__(self, policy: Policy, sigma: float, rng: np.random.Generator, part: str = "all"):
        if not (np.isfinite(sigma) and sigma >= 0):
            raise ValueError(f"noise must be a finite std >= 0, got {sigma}")
        check_choice("noise part", part, NOISE_PARTS)
        self.policy, self.sigma, self.rng, self.part = policy, float(sigma), rng, part
        self.label: np.ndarray | None = None
        self.privileged: np.ndarray | None = None

    def reset(self) -> None:
        if hasattr(self.policy, "reset"):
            self.policy.reset()

    def __call__(self, obs: dict) -> np.ndarray:
        # float64, as the env computes: the executed action is the expert's exactly when sigma is 0
        self.label = np.asarray(self.policy(obs), dtype=np.float64)
        self.privileged = getattr(self.policy, "privileged", None)  # an expert's view of the state, if any
        noise = np.zeros_like(self.label)
        if self.sigma > 0:
            draw = self.rng.standard_normal(self.label.shape)
            noise[NOISE_PARTS[self.part]] = draw[NOISE_PARTS[self.part]]
        return np.clip(self.label + self.sigma * noise, -1.0, 1.0)


def noisy(policy: Policy, sigma: float, rng: np.random.Generator, part: str = "all") -> Noisy:
    """``policy`` with executed-action noise of std ``sigma`` on ``part`` of the action; see ``Noisy``."""
    return Noisy(policy, sigma, rng, part)


def _summary(episodes: list[dict]) -> dict:
    return {"success_rate": float(np.mean([e["success"] for e in episodes])),
            "mean_max_stage": float(np.mean([e["max_stage"] for e in episodes])),
            "mean_return": float(np.mean([e["return"] for e in episodes])),
            "mean_steps": float(np.mean([e["steps"] for e in episodes])), "episodes": len(episodes)}


def per_object_summary(episodes: list[dict]) -> dict:
    """Success rate, mean highest stage, mean return and mean length, overall and per object (the
    layout of ``rl.evaluate.evaluate``, so ``markdown_table`` can print it once ``split`` is added)."""
    if not episodes:
        raise ValueError("no episodes to summarise")
    names = list(dict.fromkeys(e["object"] for e in episodes))  # first-seen order
    per_object = {name: _summary([e for e in episodes if e["object"] == name]) for name in names}
    return {**_summary(episodes), "objects": per_object}


def random_actions(n: int, seed: int = 0) -> np.ndarray:
    """Random actions (n, 22) for throughput measurements: gentle arm twists, any hand targets."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, size=(n, 22)) * np.r_[[0.3] * 6, [1.0] * 16]


def step_rate(task: str, steps: int, seed: int = 0, barrier=None, **env_kwargs) -> float:
    """env.step calls per second over ``steps`` random steps (episodes restart as they end), for the
    benchmarks; ``env_kwargs`` go to the env (e.g. ``solver_iterations``). With ``barrier`` (a
    multiprocessing barrier) the timing starts when every process sharing it is ready."""
    from dexart_lite.envs import make

    env = make(task, **env_kwargs)
    env.reset(seed=seed)
    actions = random_actions(steps, seed)
    if barrier is not None:
        barrier.wait()
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def _queued_step_rate(out, task: str, steps: int, seed: int, barrier, env_kwargs: dict) -> None:
    out.put(step_rate(task, steps, seed, barrier, **env_kwargs))


def parallel_step_rates(task: str, steps: int, processes: int, **env_kwargs) -> list[float]:
    """``step_rate`` in ``processes`` spawned processes (seeds 0, 1, ...) that start timing together: each
    one's env.step calls per second."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    barrier, out = ctx.Barrier(processes), ctx.Queue()
    procs = [ctx.Process(target=_queued_step_rate, args=(out, task, steps, seed, barrier, env_kwargs))
             for seed in range(processes)]
    for p in procs:
        p.start()
    rates = [out.get() for _ in procs]
    for p in procs:
        p.join()
    return rates
