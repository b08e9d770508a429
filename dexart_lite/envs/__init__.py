"""The four DexArt tasks as gymnasium envs (one file each) and a ``make`` by task name."""

from __future__ import annotations

import gymnasium as gym

from dexart_lite.registration import env_id


def make(task: str, **kwargs) -> gym.Env:
    """``gym.make`` by task name (faucet, bucket, laptop, toilet); keyword arguments go to the env."""
    return gym.make(env_id(task), **kwargs)
