"""The torchrl view of a DexArt task: ``make_env(task, **kwargs)``.

    GymWrapper(EpisodeInfo(GuidedStart(gym.make("DexArtLite/Laptop-v0", point_noise=True, camera_noise=True, ...))))
      + an info reader: success, stage, progress, episode_success, episode_max_stage, start_step, start_demo
      + InitTracker ("is_init"), StepCounter ("step_count"), RewardSum ("episode_reward")

``GuidedStart`` (rl/curriculum.py) is the start-state curriculum: without a level it is the env's own reset.

Tensordict keys of one step (``env.rollout`` / collector batches; ``N`` = 608 by default):

    point_cloud (N, 3) float32   observed + imagined points, robot-base frame, m
    imagined_mask (N,) int8      1 for the imagined hand points
    observation (32,) float32    the env's "state" vector (GymWrapper renames "state" to "observation")
    action (22,)                 in [-1, 1] after the env's clip
    ("next", "reward") (1,)      ("next", "done" / "terminated" / "truncated") (1,) bool
    ("next", "success") bool     ("next", "stage") int64 in 1..3    ("next", "progress") float32
    ("next", "episode_success")  success at any step of the episode so far (DexArt's metric)
    ("next", "episode_max_stage") the highest stage reached so far
    ("next", "episode_reward") (1,) return so far
    ("next", "start_step") int64 guide steps before the episode's first observation (rl/curriculum.py; 0: none)
    ("next", "start_demo") int64 the reverse curriculum's demonstration it started from, or -1

As in DexArt, training and evaluation both use point-cloud noise and camera-pose noise.
``make_env`` is a module-level function, so ``functools.partial(make_env, task, ...)`` can be sent to
spawned worker processes.
"""

from __future__ import annotations

import contextlib

import gymnasium as gym
import numpy as np
import torch
from torchrl.data import Categorical, Unbounded
from torchrl.envs import Compose, GymWrapper, InitTracker, RewardSum, StepCounter, TransformedEnv
from torchrl.envs.libs.gym import default_info_dict_reader

from dexart_lite.envs import make as make_gym_env
from dexart_lite.rl.curriculum import GuidedStart

# info keys copied into the tensordict, with their specs (one value per step)
INFO_SPECS = {
    "success": Categorical(2, shape=(), dtype=torch.bool),
    "stage": Categorical(4, shape=(), dtype=torch.int64),  # 1 reach, 2 contact, 3 manipulate
    "progress": Unbounded(shape=(), dtype=torch.float32),
    "episode_success": Categorical(2, shape=(), dtype=torch.bool),
    "episode_max_stage": Categorical(4, shape=(), dtype=torch.int64),
    "start_step": Unbounded(shape=(), dtype=torch.int64),  # guide steps before the episode's first observation
    "start_demo": Unbounded(shape=(), dtype=torch.int64),  # its demonstration (reverse curriculum) or -1
}
NUMPY_DTYPES = {torch.bool: np.bool_, torch.int64: np.int64, torch.float32: np.float32}


class EpisodeInfo(gym.Wrapper):
    """Adds ``info["episode_success"]`` (success at any step so far) and ``info["episode_max_stage"]``,
    stores the ``INFO_SPECS`` entries as numpy scalars (what torchrl's info reader expects) and
    returns a new observation dict at every call.

    DexArt counts an episode as a success if it succeeds at any step; a per-step flag read from a
    training batch cannot tell that for episodes that straddle two batches.
    """

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._success, self._max_stage = bool(info["success"]), int(info["stage"])
        return dict(obs), self._add(info)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._success = self._success or bool(info["success"])
        self._max_stage = max(self._max_stage, int(info["stage"]))
        # a fresh dict: torchrl's GymWrapper edits the dict it gets (renames "state", adds "reward"),
        # and the env hands back the same dict again when a step is cut short by sim_unstable
        return dict(obs), reward, terminated, truncated, self._add(info)

    def _add(self, info: dict) -> dict:
        info["episode_success"], info["episode_max_stage"] = self._success, self._max_stage
        info.setdefault("start_step", 0)  # without a GuidedStart below: the env's own reset
        info.setdefault("start_demo", -1)
        for key, spec in INFO_SPECS.items():  # torchrl's default_info_dict_reader expects numpy values
            info[key] = np.asarray(info[key], dtype=NUMPY_DTYPES[spec.dtype])
        return info


def make_env(task: str, *, seed: int | None = None, point_noise: bool = True, camera_noise: bool = True,
             level: dict | None = None, guide: str = "expert", guide_render: bool = True,
             **env_kwargs) -> TransformedEnv:
    """The training / evaluation env of ``task``, seeded with ``seed`` if given; ``env_kwargs`` go to
    the gymnasium env (split, object_names, num_points, imagination, randomize, max_episode_steps, ...).
    ``level``, ``guide``, ``guide_render``: the start-state curriculum (``rl/curriculum.GuidedStart``;
    None: the env's own resets), whose guide steps happen inside the reset and are never collected."""
    gym_env = make_gym_env(task, point_noise=point_noise, camera_noise=camera_noise, **env_kwargs)
    gym_env = EpisodeInfo(GuidedStart(gym_env, level, guide, guide_render))
    env = GymWrapper(gym_env)
    env.set_info_dict_reader(default_info_dict_reader(list(INFO_SPECS), spec=dict(INFO_SPECS)))
    env = TransformedEnv(env, Compose(InitTracker(), StepCounter(), RewardSum()))
    if seed is not None:
        env.set_seed(seed)
    return env


def env_dims(env) -> tuple[int, int, int]:
    """``(num_points, state_dim, action_dim)`` of a torchrl env from ``make_env`` (0 points for the
    state-only observation)."""
    obs = env.observation_spec
    points = obs["point_cloud"].shape[-2] if "point_cloud" in obs.keys() else 0
    return points, obs["observation"].shape[-1], env.action_spec.shape[-1]


@contextlib.contextmanager
def torch_threads(n: int):
    """Run the block with ``n`` torch threads, then restore the previous number.

    Acting one step at a time (evaluation, in-process collection) is fastest on one thread: on a
    busy 2-core machine, two threads made one small-encoder action 3-15x slower (1.5-2.3 ms
    against 6-38 ms, measured while other jobs ran).
    """
    before = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(before)
