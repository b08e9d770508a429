"""The PPO actor-critic of DexArt, as a torchrl ``ActorValueOperator`` with a shared trunk.

    point_cloud (..., 608, 3) --PointNetEncoder--> (..., 256) --+
                                                                 +--> hidden (..., 320)
    observation (..., 32)  --Linear-ReLU-Linear--> (..., 64) ---+
    hidden --[64, 64] ReLU--> Linear --> loc (..., 22); scale = exp(log_std), log_std a free parameter
    hidden --[64, 64] ReLU--> Linear --> state_value (..., 1)

This is SB3's ``ActorCriticPolicy`` with DexArt's ``PointNetImaginationExtractorGP`` (608 xyz
points: 512 observed + 96 imagined; the imagined-point mask is not an input) and its
initialisation: orthogonal weights with gain sqrt(2) for the trunk and the hidden layers, 0.01 for
the action layer and 1 for the value layer, zero biases; then the PointNet is re-initialised with
its own truncated normal (std 0.02). The action distribution is an unsquashed diagonal Gaussian
with state-independent log-std starting at 0; the env clips actions to [-1, 1], as SB3 does.

The trunk runs once per minibatch in the PPO loss: the loss gets ``get_value_head()`` as critic
and reuses the ``hidden`` the actor wrote (torchrl-0.14 notes, section 0.5).
"""

from __future__ import annotations

import math

import torch
from tensordict.nn import AddStateIndependentNormalScale, TensorDictModule, TensorDictModuleBase
from tensordict.nn.probabilistic import interaction_type
from torch import nn
from torchrl.data import Bounded
from torchrl.envs.utils import ExplorationType
from torchrl.modules import ActorValueOperator, IndependentNormal, ProbabilisticActor, ValueOperator

from dexart_lite.models.depth_cnn import DepthCNN
from dexart_lite.models.pointnet import ENCODER_SIZES, FEATURE_DIM, PointNetEncoder

POINTS_KEY = "point_cloud"  # (..., N, 3) float32, robot-base frame, m
STATE_KEY = "observation"  # the env's "state" vector; torchrl's GymWrapper renames "state" to "observation"
IMAGE_KEY = "depth_image"  # (..., 64, 64) float32, m: the 2-D baseline's input (env depth_image=True)
# the trunk's encoders: DexArt's three PointNets, the 2-D baseline's CNN on the depth image, and "none"
# (the state-only diagnostic: the state MLP alone, on a state vector that carries the object's pose)
ENCODERS = (*ENCODER_SIZES, "depth_cnn", "none")
HIDDEN_KEY = "hidden"  # (..., 320) trunk output
STATE_HIDDEN = 64
HEAD_HIDDEN = (64, 64)


class Trunk(nn.Module):
    """PointNet on the cloud, concatenated with an MLP on the state vector.

    With ``normalize`` (not DexArt's: its inputs are raw), both inputs first go through a fixed affine
    map, ``(x - loc) / scale``, whose buffers are set once from data (``set_normalization``) and travel
    in the weights: the state vector per entry, the points with one centre (3,) and one scale, so the
    cloud keeps its shape.
    """

    def __init__(self, state_dim: int, encoder_size: str = "small", normalize: bool = False,
                 state_hidden: int = STATE_HIDDEN):
        super().__init__()
        # the 2-D baseline reads the depth image instead of the cloud (the point normalisation then stays unused)
        self.image = encoder_size == "depth_cnn"
        if encoder_size == "none":
            self.encoder = None
        else:
            self.encoder = DepthCNN() if self.image else PointNetEncoder(encoder_size)
        # DexArt: 64 units; wider for the state-only diagnostic's clone of the expert (PPOConfig.state_hidden)
        self.state_mlp = nn.Sequential(nn.Linear(state_dim, state_hidden), nn.ReLU(),
                                       nn.Linear(state_hidden, state_hidden))
        self.out_dim = (0 if self.encoder is None else FEATURE_DIM) + state_hidden
        self.normalize = normalize
        if normalize:
            self.register_buffer("state_loc", torch.zeros(state_dim))
            self.register_buffer("state_scale", torch.ones(state_dim))
            self.register_buffer("point_loc", torch.zeros(3))
            self.register_buffer("point_scale", torch.ones(1))
            self.register_buffer("state_mask", torch.ones(state_dim))  # 0: an entry the network never sees

    @torch.no_grad()
    def set_normalization(self, states: torch.Tensor, points: torch.Tensor | None, drop: list[int] | None = None) -> None:
        """Centre and scale from samples: ``states`` (S, D), ``points`` (S, N, 3) (m; None: the points stay
        raw, e.g. for a pretrained PointNet that learnt on raw metres). ``drop``: state entries zeroed
        after normalisation (e.g. t / horizon, which a student can use as a clock)."""
        if not self.normalize:
            raise ValueError("this trunk was built with normalize=False")
        self.state_loc.copy_(states.mean(0))
        self.state_scale.copy_(states.std(0).clamp_min(1e-2))  # constant entries (t/T at reset...) stay finite
        self.state_mask.fill_(1.0)
        if drop:
            self.state_mask[list(drop)] = 0.0
        if points is None:
            self.point_loc.zero_()
            self.point_scale.fill_(1.0)
            return
        flat = points.reshape(-1, 3)
        self.point_loc.copy_(flat.mean(0))
        self.point_scale.copy_(flat.std(0).mean().clamp_min(1e-3).reshape(1))

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        """points (..., N, 3) (the 2-D baseline: a depth image (..., 64, 64)), state (..., D) -> (..., 320);
        with no encoder, state (..., D) alone -> (..., 64)."""
        *points, state = inputs  # points: [] without an encoder
        if self.normalize:
            state = (state - self.state_loc) / self.state_scale * self.state_mask
        features = self.state_mlp(state)
        if self.encoder is None:
            return features
        points = points[0]
        if self.normalize and not self.image:
            points = (points - self.point_loc) / self.point_scale
        return torch.cat([self.encoder(points), features], dim=-1)


def mlp(in_dim: int, hidden: tuple[int, ...], out_dim: int) -> nn.Sequential:
    """Linear-ReLU layers of widths ``hidden``, then a final Linear to ``out_dim``."""
    layers: list[nn.Module] = []
    for width in hidden:
        layers += [nn.Linear(in_dim, width), nn.ReLU()]
        in_dim = width
    return nn.Sequential(*layers, nn.Linear(in_dim, out_dim))


def orthogonal_init(module: nn.Module, gain: float) -> None:
    """SB3's ``init_weights``: orthogonal weights with ``gain``, zero biases, on every Linear."""
    for layer in module.modules():
        if isinstance(layer, nn.Linear):
            nn.init.orthogonal_(layer.weight, gain=gain)
            nn.init.zeros_(layer.bias)


def make_actor_critic(state_dim: int, action_dim: int = 22, encoder: str = "small",
                      init_log_std: float = 0.0, head: tuple[int, ...] = HEAD_HIDDEN,
                      normalize: bool = False, state_hidden: int = STATE_HIDDEN) -> ActorValueOperator:
    """The shared-trunk actor-critic; the actions' standard deviation starts at ``exp(init_log_std)``
    (DexArt / SB3: 0, i.e. std 1). ``head``: hidden widths of the policy and value MLPs (DexArt: 64, 64);
    ``normalize``: fixed input normalisation in the trunk (``Trunk``; DexArt: none); ``state_hidden``: width
    of the trunk's state MLP (DexArt: 64).

    ``get_policy_operator()`` goes to the collector and the loss's actor; ``get_value_operator()``
    (trunk + value head) to GAE; ``get_value_head()`` to the loss's critic.
    """
    trunk = Trunk(state_dim, encoder, normalize, state_hidden)
    policy_net = mlp(trunk.out_dim, tuple(head), action_dim)
    value_net = mlp(trunk.out_dim, tuple(head), 1)
    orthogonal_init(trunk, math.sqrt(2))
    orthogonal_init(policy_net[:-1], math.sqrt(2))
    orthogonal_init(value_net[:-1], math.sqrt(2))
    orthogonal_init(policy_net[-1], 0.01)
    orthogonal_init(value_net[-1], 1.0)
    if isinstance(trunk.encoder, PointNetEncoder):
        trunk.encoder.reset_parameters()  # the PointNet keeps its own init (pretrained weights load over it)

    in_keys = [STATE_KEY] if encoder == "none" else [input_key(encoder), STATE_KEY]
    trunk_module = TensorDictModule(trunk, in_keys=in_keys, out_keys=[HIDDEN_KEY])
    log_std = AddStateIndependentNormalScale(action_dim, init_value=init_log_std)  # scale = exp(log_std)
    loc_scale = TensorDictModule(nn.Sequential(policy_net, log_std), in_keys=[HIDDEN_KEY], out_keys=["loc", "scale"])
    action_spec = Bounded(low=-1.0, high=1.0, shape=(action_dim,), dtype=torch.float32)
    policy_head = ProbabilisticActor(loc_scale, in_keys=["loc", "scale"], out_keys=["action"], spec=action_spec,
                                     distribution_class=IndependentNormal, distribution_kwargs={"tanh_loc": False},
                                     return_log_prob=True,  # writes "action_log_prob"
                                     default_interaction_type=ExplorationType.RANDOM)  # eval: set DETERMINISTIC
    value_head = ValueOperator(value_net, in_keys=[HIDDEN_KEY])  # writes "state_value" (..., 1)
    return ActorValueOperator(trunk_module, policy_head, value_head)


class DetachedInput(nn.Module):
    """``net`` applied to a detached input: its own parameters learn, nothing upstream does (PPO's
    ``--critic-detach``: the value MLP on a detached copy of the trunk's features)."""

    def __init__(self, net: nn.Module):
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x.detach())


class Acting(TensorDictModuleBase):
    """``actor_critic(td)`` for acting, on the same modules (the weights are shared, not copied).

    Writes what the whole actor-critic writes, less the trunk's ``hidden``: ``loc``, ``scale``,
    ``action``, ``action_log_prob`` and ``state_value``, with the same numbers (a test checks them,
    the random action included). tensordict's generic modules cost about as much as the small
    network they wrap: one action on one observation, 1 thread, takes 1.27 ms as ``actor_critic(td)``
    and 0.77 ms here (``benchmarks/perf/bench_training.py``, ``policy_call_ms``; each module output write
    even searches ``sys.path`` for pandas). This class goes to the collectors and acts in evaluation
    and DAgger; the loss keeps the torchrl modules.

    The action follows tensordict's interaction type as ``ProbabilisticActor`` does: the mean under
    ``set_exploration_type(DETERMINISTIC / MODE / MEAN)``, otherwise (RANDOM, the default of the
    actor) a sample ``loc + scale * eps`` drawn as ``Normal.rsample`` draws it.
    """

    def __init__(self, actor_critic: ActorValueOperator):
        super().__init__()
        trunk_module, policy_head, value_head = actor_critic.module
        self.trunk = trunk_module.module
        self.loc_scale = policy_head.module[0].module  # policy MLP, then the state-independent scale
        self.value_net = value_head.module
        self.in_keys = list(trunk_module.in_keys)
        self.out_keys = ["loc", "scale", "action", "action_log_prob", "state_value"]

    def forward(self, tensordict):
        hidden = self.trunk(*(tensordict.get(key) for key in self.in_keys))  # (..., 320)
        loc, scale = self.loc_scale(hidden)  # (..., action_dim) each
        if interaction_type() in (ExplorationType.DETERMINISTIC, ExplorationType.MODE, ExplorationType.MEAN):
            action = loc
        else:
            action = loc + torch.empty_like(loc).normal_() * scale  # Normal.rsample's draw
        # summed over the action dimensions, as IndependentNormal.log_prob (no argument checks: hot path)
        log_prob = torch.distributions.Normal(loc, scale, validate_args=False).log_prob(action).sum(-1)
        for key, value in zip(self.out_keys, (loc, scale, action, log_prob, self.value_net(hidden))):
            tensordict.set(key, value)
        return tensordict


def architecture(dims: dict) -> dict:
    """``make_actor_critic`` keywords recorded in a checkpoint's ``dims`` (absent: DexArt's)."""
    return {"head": tuple(dims.get("head", HEAD_HIDDEN)), "normalize": bool(dims.get("normalize", False)),
            "state_hidden": int(dims.get("state_hidden", STATE_HIDDEN))}


def input_key(encoder: str) -> str:
    """The observation an encoder reads: the point cloud, or the depth image for ``depth_cnn``."""
    return IMAGE_KEY if encoder == "depth_cnn" else POINTS_KEY


def encoder_label(encoder: str) -> str:
    """How reports name an encoder: "small PointNet", ..., or "depth-image CNN"."""
    return {"depth_cnn": "depth-image CNN", "none": "state MLP"}.get(encoder, f"{encoder} PointNet")


def trunk_of(actor_critic: ActorValueOperator) -> Trunk:
    """The ``Trunk`` of ``actor_critic``."""
    return actor_critic.module[0].module  # module[0] is the trunk TensorDictModule


def encoder_of(actor_critic: ActorValueOperator) -> PointNetEncoder:
    """The ``PointNetEncoder`` inside the trunk of ``actor_critic``."""
    return actor_critic.module[0].module.encoder  # module[0] is the trunk TensorDictModule


def action_log_std(actor_critic: ActorValueOperator) -> torch.Tensor:
    """The state-independent log-std of the action distribution, (action_dim,)."""
    scale = next(m for m in actor_critic.modules() if isinstance(m, AddStateIndependentNormalScale))
    return scale.state_independent_scale.detach()


@torch.no_grad()
def set_action_log_std(actor_critic: ActorValueOperator, value: float) -> None:
    """Set every entry of the state-independent log-std to ``value`` (e.g. a distilled student, whose
    MSE training left it at its initial value, before PPO fine-tuning)."""
    scale = next(m for m in actor_critic.modules() if isinstance(m, AddStateIndependentNormalScale))
    scale.state_independent_scale.fill_(value)
