"""The learners ``dexart-lite train --algo`` runs, by name: ``LEARNERS``, the one place that tells them apart.

    spec = LEARNERS["sac"]
    result = spec.train(spec.config(task="laptop", frames=10_000))   # SACConfig, rl/sac.py's train
    net = spec.policy(payload["dims"], "none")                        # what a checkpoint's "model" weights fit

Each entry names the module that holds the learner's config class, ``train(cfg) -> dict`` and
``config_from_args(args)``; the module is imported on first use (as gymnasium's string entry points), so
that loading a checkpoint (``rl/checkpoint.py``, which the learners themselves import) does not import the
training code. A run's config says which learner it belongs to with ``algo``; a config without one (PPO's, a
distilled student's: both networks are PPO's actor-critic) is ``"ppo"``'s.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable

import torch

from dexart_lite.models.actor_critic import architecture, make_actor_critic
from dexart_lite.models.soft_actor_critic import make_sac_actor
from dexart_lite.utils import check_choice


def actor_critic(dims: dict, encoder: str) -> torch.nn.Module:
    """PPO's shared-trunk actor-critic (also a distilled student's) of a checkpoint's ``dims``."""
    return make_actor_critic(dims["state_dim"], dims["action_dim"], encoder, **architecture(dims))


def sac_actor(dims: dict, encoder: str) -> torch.nn.Module:
    """The off-policy learner's tanh-Gaussian actor of a checkpoint's ``dims`` (its checkpoint's ``model``)."""
    return make_sac_actor(dims["state_dim"], dims["action_dim"], encoder, tuple(dims["head"]), dims["state_hidden"])


@dataclass(frozen=True)
class LearnerSpec:
    """One learner: where its code lives and how its checkpoints' networks are built."""

    module: str  # defines the config class, train(cfg) -> dict and config_from_args(args)
    config_name: str
    policy: Callable[[dict, str], torch.nn.Module]  # (checkpoint dims, trunk encoder) -> network

    @property
    def config(self) -> type:
        """The learner's config dataclass."""
        return getattr(importlib.import_module(self.module), self.config_name)

    def train(self, cfg) -> dict:
        """Train, evaluate and report (the module's ``train``)."""
        return importlib.import_module(self.module).train(cfg)

    def config_from_args(self, args):
        """The config of ``dexart-lite train``'s parsed command line (the module's ``config_from_args``)."""
        return importlib.import_module(self.module).config_from_args(args)


LEARNERS: dict[str, LearnerSpec] = {
    "ppo": LearnerSpec("dexart_lite.rl.ppo", "PPOConfig", actor_critic),  # DexArt's learner, the default
    "sac": LearnerSpec("dexart_lite.rl.sac", "SACConfig", sac_actor),  # off-policy, demonstrations in its buffer
}


def learner_name(cfg) -> str:
    """The learner a run's config (a dataclass, or the dict a checkpoint keeps) belongs to: its ``algo``, else
    ``"ppo"``."""
    algo = cfg.get("algo", "ppo") if isinstance(cfg, dict) else getattr(cfg, "algo", "ppo")
    check_choice("learner (algo)", algo, LEARNERS)
    return algo


def learner_of(cfg) -> LearnerSpec:
    """The ``LEARNERS`` entry of a run's config (see ``learner_name``)."""
    return LEARNERS[learner_name(cfg)]
