"""PPO checkpoints: one ``torch.save`` file holding the config, the network sizes, the weights, the
optimizer, the frame count and the learning-curve history. Missing or unreadable files raise a
one-line ``FileNotFoundError`` / ``ValueError``; a file whose weights do not fit the network it
describes raises ``ValueError`` too.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np
import torch
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import ActorValueOperator

from dexart_lite.models.actor_critic import IMAGE_KEY, POINTS_KEY, STATE_KEY, Acting
from dexart_lite.rl.learners import learner_of

FILE_FORMAT = "dexart_lite.ppo"
FILE_VERSION = 1
REQUIRED = ("config", "dims", "model", "frames", "batches", "history")


def save_checkpoint(path: str | os.PathLike, payload: dict) -> Path:
    """Write ``payload`` (see ``REQUIRED``) atomically: a crash mid-write leaves the old file."""
    missing = [k for k in REQUIRED if k not in payload]
    if missing:
        raise ValueError(f"checkpoint payload lacks {missing}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    torch.save({"format": FILE_FORMAT, "version": FILE_VERSION, **payload}, tmp)
    os.replace(tmp, path)
    return path


def checkpoint_path(spec: str | os.PathLike) -> Path:
    """The file of a checkpoint argument: a path, or ``zoo:<task>`` for a policy shipped in ``dexart_lite.zoo``
    (an unknown name or a missing file: a one-line error naming the valid entries)."""
    from dexart_lite import zoo

    return zoo.resolve(spec) if zoo.is_zoo(spec) else Path(spec)


def load_checkpoint(path: str | os.PathLike) -> dict:
    """The payload of a checkpoint written by ``save_checkpoint``; ``zoo:<task>`` names a shipped one."""
    path = checkpoint_path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint not found: {path}")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # truncated zip, random bytes, a pickle of something else...
        detail = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise ValueError(f"{path} is not a readable checkpoint ({detail[:200]})") from None
    if not isinstance(payload, dict) or payload.get("format") != FILE_FORMAT:
        raise ValueError(f"{path} is not a dexart_lite PPO checkpoint (written by `dexart-lite train`)")
    missing = [k for k in REQUIRED if k not in payload]
    if missing:
        raise ValueError(f"{path} is an incomplete PPO checkpoint: it lacks {missing}")
    return payload


def observation_kwargs(payload: dict) -> dict:
    """The env keywords that give a checkpoint's network the observation it was trained on: its cloud
    size, the imagined points (on unless switched off) and, for the 2-D baseline, the depth image; and
    the action it gives (the synergy hand's 9-D action)."""
    cfg = payload["config"]
    kwargs = {"num_points": cfg["num_points"], "imagination": cfg.get("imagination", True)}
    if cfg.get("encoder") == "depth_cnn":
        kwargs["depth_image"] = True
    if cfg.get("obs", "cloud") != "cloud":
        kwargs["observation"] = cfg["obs"]
    if cfg.get("hand", "joints") != "joints":  # the action it was trained to give
        kwargs["hand"] = cfg["hand"]
    return kwargs


def network_encoder(cfg: dict) -> str:
    """The trunk's encoder of a run's config: ``encoder``, or "none" for the state-only observation."""
    return "none" if cfg.get("obs", "cloud") == "state" else cfg["encoder"]


def actor_critic_from_checkpoint(payload: dict, path: str | os.PathLike = "checkpoint") -> ActorValueOperator:
    """The policy network described by ``payload["dims"]`` with its weights loaded strictly: the one its learner
    builds (``rl/learners.py``: the PPO / distill actor-critic, or the off-policy run's tanh-Gaussian actor)."""
    dims, cfg = payload["dims"], payload["config"]
    actor_critic = learner_of(cfg).policy(dims, network_encoder(cfg))
    try:
        actor_critic.load_state_dict(payload["model"], strict=True)
    except RuntimeError as err:
        detail = " ".join(str(err).split())
        raise ValueError(f"{path}: weights do not fit a {cfg['encoder']!r} actor-critic ({detail[:300]})") from None
    return actor_critic


def policy_function(actor_critic, device: torch.device | None = None) -> Callable[[dict], np.ndarray]:
    """A gymnasium-observation -> action function with deterministic actions, clipped to [-1, 1], of an
    actor-critic or of any module that writes ``action`` (the off-policy learner's actor). ``device``: where
    the network is (the observation goes there, the action comes back); None: the CPU."""
    # the actor-critic's outputs without tensordict's per-module overhead
    policy = Acting(actor_critic) if isinstance(actor_critic, ActorValueOperator) else actor_critic
    on_device = device is not None and torch.device(device).type != "cpu"

    def act(obs: dict) -> np.ndarray:
        td = TensorDict({STATE_KEY: torch.as_tensor(obs["state"])}, [])
        if "point_cloud" in obs:  # absent from the state-only observation
            td[POINTS_KEY] = torch.as_tensor(obs["point_cloud"])
        if "depth_image" in obs:  # the 2-D baseline's input (env depth_image=True)
            td[IMAGE_KEY] = torch.as_tensor(obs["depth_image"])
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            if on_device:
                return policy(td.to(device))["action"].clamp(-1.0, 1.0).cpu().numpy()
            return policy(td)["action"].clamp(-1.0, 1.0).numpy()

    return act


def load_policy(path: str | Path, env=None) -> Callable[[dict], np.ndarray]:
    """The deterministic policy of a checkpoint, for a gymnasium env (used by ``dexart-lite render``)."""
    payload = load_checkpoint(path)
    if env is not None:
        state_dim = env.observation_space["state"].shape[0]
        if state_dim != payload["dims"]["state_dim"]:
            raise ValueError(f"{path} was trained on {payload['config']['task']} (state of "
                             f"{payload['dims']['state_dim']}); this env's state has {state_dim} entries")
    return policy_function(actor_critic_from_checkpoint(payload, path))
