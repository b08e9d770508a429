"""The task names, the episode length and the gymnasium ids, registered without importing the envs.

Registration uses string entry points, so ``import dexart_lite`` stays light (no PyBullet) and the
ids also exist in spawned worker processes, which re-import the package.
"""

from __future__ import annotations

import gymnasium as gym

from dexart_lite.utils import check_choice

TASKS = ("faucet", "bucket", "laptop", "toilet")
HORIZON = 250  # control steps per episode (10 s at 25 Hz): the registered max_episode_steps
OBSERVATIONS = ("cloud", "state")  # the env's ``observation``: DexArt's point cloud + state; the state-only diagnostic
HAND_MODES = ("joints", "synergy")  # the env's ``hand``: DexArt's 16 joint targets; 3 synergies (robot.py)
ENV_IDS = [f"DexArtLite/{task.capitalize()}-v0" for task in TASKS]


def env_id(task: str) -> str:
    """The gymnasium id of ``task``; ``ValueError`` listing the tasks if unknown."""
    check_choice("task", task, TASKS)
    return f"DexArtLite/{task.capitalize()}-v0"


def register_all() -> None:
    for task, id_ in zip(TASKS, ENV_IDS):
        if id_ not in gym.registry:
            gym.register(id=id_, entry_point=f"dexart_lite.envs.{task}:{task.capitalize()}Env",
                         max_episode_steps=HORIZON)
