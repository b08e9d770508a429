"""The networks of the off-policy learner (``rl/sac.py``): a tanh-Gaussian actor and a Q-network, each on its
own ``Trunk`` (the PPO actor-critic's: a PointNet on the cloud, or none, and an MLP on the state vector).

    observation (..., D) [+ point_cloud (..., N, 3)] --Trunk--> (..., F) --MLP--> loc, scale (..., A)
        action = tanh(loc + scale * eps)  (TanhNormal in [-1, 1]; deterministic: tanh(loc))
    observation [+ point_cloud] --Trunk--> (..., F), action (..., A) --MLP with LayerNorm--> Q (..., 1)

As in RLPD (Ball et al. 2023), every hidden layer of the Q-network is Linear -> LayerNorm -> ReLU: it keeps
the critics from extrapolating wildly to actions the demonstrations never show. The actor and the critics
do not share a trunk (SAC's usual layout; a shared PointNet would let the critic's larger gradients reshape
the actor's features). Both trunks normalise their inputs with fixed statistics set from data before
training (``Trunk.set_normalization``).
"""

from __future__ import annotations

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.data import Bounded
from torchrl.modules import ProbabilisticActor, TanhNormal, ValueOperator

from dexart_lite.models.actor_critic import POINTS_KEY, STATE_KEY, Trunk, mlp

SAC_HIDDEN = (256, 256)


def ln_mlp(in_dim: int, hidden: tuple[int, ...], out_dim: int) -> nn.Sequential:
    """Linear-LayerNorm-ReLU layers of widths ``hidden``, then a final Linear to ``out_dim`` (RLPD's critic)."""
    layers: list[nn.Module] = []
    for width in hidden:
        layers += [nn.Linear(in_dim, width), nn.LayerNorm(width), nn.ReLU()]
        in_dim = width
    return nn.Sequential(*layers, nn.Linear(in_dim, out_dim))


class ActorNet(nn.Module):
    """(points,) state -> (loc, scale), each (..., A); scale = softplus(x + 0.54) + 1e-4 (torchrl's biased softplus)."""

    def __init__(self, state_dim: int, action_dim: int, encoder: str, hidden: tuple[int, ...], state_hidden: int):
        super().__init__()
        self.trunk = Trunk(state_dim, encoder, normalize=True, state_hidden=state_hidden)
        self.net = mlp(self.trunk.out_dim, hidden, 2 * action_dim)
        self.extractor = NormalParamExtractor()

    def forward(self, *inputs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return self.extractor(self.net(self.trunk(*inputs)))


class QNet(nn.Module):
    """(points,) state, action -> Q (..., 1)."""

    def __init__(self, state_dim: int, action_dim: int, encoder: str, hidden: tuple[int, ...], state_hidden: int,
                 layer_norm: bool = True):
        super().__init__()
        self.trunk = Trunk(state_dim, encoder, normalize=True, state_hidden=state_hidden)
        self.net = (ln_mlp if layer_norm else mlp)(self.trunk.out_dim + action_dim, hidden, 1)

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        *observation, action = inputs
        return self.net(torch.cat([self.trunk(*observation), action], dim=-1))


def observation_keys(encoder: str) -> list[str]:
    """The tensordict keys a network with ``encoder`` reads ("none": the state vector alone)."""
    return [STATE_KEY] if encoder == "none" else [POINTS_KEY, STATE_KEY]


def make_sac_actor(state_dim: int, action_dim: int = 22, encoder: str = "none", hidden: tuple[int, ...] = SAC_HIDDEN,
                   state_hidden: int = 256) -> ProbabilisticActor:
    """The tanh-Gaussian policy; writes ``loc``, ``scale`` and ``action`` (a sample, or tanh(loc) under
    DETERMINISTIC exploration)."""
    net = ActorNet(state_dim, action_dim, encoder, tuple(hidden), state_hidden)
    module = TensorDictModule(net, in_keys=observation_keys(encoder), out_keys=["loc", "scale"])
    spec = Bounded(low=-1.0, high=1.0, shape=(action_dim,), dtype=torch.float32)
    return ProbabilisticActor(module, in_keys=["loc", "scale"], out_keys=["action"], spec=spec,
                              distribution_class=TanhNormal, distribution_kwargs={"low": -1.0, "high": 1.0},
                              return_log_prob=False)


def make_qvalue(state_dim: int, action_dim: int = 22, encoder: str = "none", hidden: tuple[int, ...] = SAC_HIDDEN,
                state_hidden: int = 256, layer_norm: bool = True) -> ValueOperator:
    """Q(s, a); writes ``state_action_value`` (..., 1). ``SACLoss`` makes its ensemble of copies."""
    net = QNet(state_dim, action_dim, encoder, tuple(hidden), state_hidden, layer_norm)
    return ValueOperator(net, in_keys=[*observation_keys(encoder), "action"])


def sac_trunk(module: ProbabilisticActor | ValueOperator) -> Trunk:
    """The ``Trunk`` inside a network of this module (for its input normalisation)."""
    net = module.module[0].module if isinstance(module, ProbabilisticActor) else module.module
    return net.trunk


__all__ = ["ActorNet", "QNet", "SAC_HIDDEN", "ln_mlp", "make_qvalue", "make_sac_actor", "observation_keys", "sac_trunk"]
