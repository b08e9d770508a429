"""``PointNetEncoder``: the one PointNet of dexart_lite, and its strict save / load contract.

As in DexArt (``stable_baselines3/networks/pretrain_nets.py``): a per-point MLP on xyz with GELU
between layers, a global max-pool over the points, a 256-D feature. No BatchNorm, no T-Net.

    small   3 -> 64 -> 256                          (DexArt's ``smallpn``, used for all main results)
    medium  3 -> 64 -> 64 -> 128 -> 256             (three hidden layers)
    large   3 -> 64 -> 64 -> 128 -> 128 -> 256 -> 256   (five hidden layers)

Weights are initialised from a truncated normal (std 0.02, biases 0). Pretraining, RL and the
tutorials all use this class; encoder weights travel on their own (``save_encoder`` /
``load_encoder``) and are always loaded strictly: a file written for another size, a different
class or a corrupt file raises a one-line ``ValueError``.
"""

from __future__ import annotations

import os
from pathlib import Path

import torch
from torch import nn

from dexart_lite.utils import check_choice

# size -> per-point layer widths after the 3 input coordinates; the last one is the feature size
ENCODER_SIZES: dict[str, tuple[int, ...]] = {
    "small": (64, 256),
    "medium": (64, 64, 128, 256),
    "large": (64, 64, 128, 128, 256, 256),
}
FEATURE_DIM = 256
FILE_FORMAT = "dexart_lite.PointNetEncoder"  # marks files written by save_encoder
FILE_VERSION = 1
# clouds per per-point pass: (8, 608, 256) float32 activations (5 MB) stay nearer the cores than one
# pass over the whole batch. 32 was measured 1.5-2x faster than no chunks on a Xeon VM; on the AMD EPYC
# VM 8 trains the large PointNet 1.35x, the medium 1.04x and the small 1.13x faster than 32 (the same
# losses; benchmarks/perf/bench_student_training.py --chunks, results/perf/bench_student_training_chunks.json)
CHUNK = 8


class PointNetEncoder(nn.Module):
    """Per-point MLP + max-pool: ``points (..., N, 3) -> feature (..., 256)``."""

    def __init__(self, size: str = "small", in_channels: int = 3):
        super().__init__()
        check_choice("encoder size", size, ENCODER_SIZES)
        self.size, self.in_channels = size, in_channels  # in_channels > 3: xyz plus per-point features
        layers: list[nn.Module] = []
        width = in_channels
        for i, out in enumerate(ENCODER_SIZES[size]):
            if i > 0:
                layers.append(nn.GELU())
            layers.append(nn.Linear(width, out))
            width = out
        self.mlp = nn.Sequential(*layers)
        self.feature_dim = width
        self.reset_parameters()

    def reset_parameters(self) -> None:
        """Truncated-normal weights (std 0.02; DexArt's call, whose default cut at +-2 is absolute,
        i.e. 100 std: in effect a normal), zero biases."""
        for module in self.mlp:
            if isinstance(module, nn.Linear):
                nn.init.trunc_normal_(module.weight, std=0.02)
                nn.init.zeros_(module.bias)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        """points: (..., N, 3) xyz in m -> (..., feature_dim), max over the N points.

        Without autograd this is ``mlp(points).max(-2)``. With autograd the result and the
        gradients are the same (up to float rounding), computed for a fraction of the cost:
        the gradient of a max-pool reaches only the winning point of each channel, so the full
        per-point pass runs without autograd, only to find the winners, and autograd sees a
        recomputation of the winning points alone, each once (one point often wins many channels:
        ~26 distinct winners of 256 channels per cloud at initialisation, ~45 in a trained laptop
        student), then the last layer's channel f on channel f's winner (measured in
        benchmarks/perf/bench_training.py; the PPO update is the CPU bottleneck).
        """
        c = self.in_channels
        if points.shape[-1] != c or points.dim() < 2:
            raise ValueError(f"points must have shape (..., N, {c}), got {tuple(points.shape)}")
        lead, n = points.shape[:-2], points.shape[-2]
        flat = points.reshape(-1, n, c)  # (B, N, C)
        if not (torch.is_grad_enabled() and (points.requires_grad or any(p.requires_grad for p in self.parameters()))):
            pooled = torch.cat([self.mlp(chunk).max(dim=-2).values for chunk in flat.split(CHUNK)])  # (B, F)
            return pooled.reshape(*lead, self.feature_dim)
        with torch.no_grad():
            winner = torch.cat([self.mlp(chunk).max(dim=-2).indices for chunk in flat.split(CHUNK)])  # (B, F)
        # the distinct winning points of the whole batch, as indices into the (B * N) points (a mask
        # and a running count instead of torch.unique, whose sort costs more than it saves)
        index = winner + n * torch.arange(len(flat), device=winner.device).unsqueeze(1)  # (B, F)
        wins = torch.zeros(flat.shape[0] * n, dtype=torch.bool, device=winner.device)
        wins[index.reshape(-1)] = True
        distinct = wins.nonzero().squeeze(1)  # (M,) ascending
        channel_point = (torch.cumsum(wins, 0) - 1)[index]  # (B, F): channel f's winner's place in distinct
        hidden = self.mlp[:-1](flat.reshape(-1, c)[distinct])  # (M, H): the layers before the last one
        hidden = hidden[channel_point]  # (B, F, H): at channel f's winning point
        last = self.mlp[-1]
        feature = (hidden * last.weight).sum(-1) + last.bias  # (B, F): channel f of the last layer only
        return feature.reshape(*lead, self.feature_dim)

    def per_point(self, points: torch.Tensor) -> torch.Tensor:
        """points: (..., N, in_channels) -> per-point features (..., N, feature_dim) before pooling."""
        return self.mlp(points)

    def extra_repr(self) -> str:
        return f"size={self.size!r}" + (f", in_channels={self.in_channels}" if self.in_channels != 3 else "")


def save_encoder(encoder: PointNetEncoder, path: str | os.PathLike) -> Path:
    """Write ``encoder``'s weights and size to ``path`` (a ``torch.save`` file); returns the path."""
    if not isinstance(encoder, PointNetEncoder):
        raise TypeError(f"save_encoder expects a PointNetEncoder, got {type(encoder).__name__}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().cpu().clone() for k, v in encoder.state_dict().items()}
    torch.save({"format": FILE_FORMAT, "version": FILE_VERSION, "size": encoder.size, "state_dict": state}, path)
    return path


def read_encoder_file(path: str | os.PathLike) -> tuple[str, dict[str, torch.Tensor]]:
    """``(size, state_dict)`` from a file of ``save_encoder``; one-line errors for anything else."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"encoder file not found: {path}")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # truncated zip, pickle garbage, wrong file type...
        first_line = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise ValueError(f"{path} is not a readable encoder file ({first_line})") from None
    if not isinstance(payload, dict) or payload.get("format") != FILE_FORMAT:
        raise ValueError(f"{path} is not an encoder file written by dexart_lite.models.save_encoder "
                         f"(a PPO checkpoint? use the 'encoder' inside it, or dexart_lite.rl.ppo.load_checkpoint)")
    size, state = payload.get("size"), payload.get("state_dict")
    if size not in ENCODER_SIZES or not isinstance(state, dict):
        raise ValueError(f"{path} has an unknown encoder size {size!r} or no weights")
    return size, state


def load_encoder(path: str | os.PathLike, encoder: PointNetEncoder | None = None, strict: bool = True) -> PointNetEncoder:
    """Load encoder weights from ``path``; returns the encoder.

    Into a new encoder of the file's size when ``encoder`` is None, otherwise into ``encoder``
    in place (e.g. the PointNet inside an actor-critic). With ``strict`` (the default and what
    every dexart_lite entry point uses) any missing, unexpected or mis-shaped weight, or a size
    mismatch, raises ``ValueError``.
    """
    size, state = read_encoder_file(path)
    if encoder is None:
        encoder = PointNetEncoder(size)
    if strict and size != encoder.size:
        raise ValueError(f"{path} holds a {size!r} PointNetEncoder but the model has a {encoder.size!r} one")
    own = encoder.state_dict()
    missing = sorted(set(own) - set(state))
    unexpected = sorted(set(state) - set(own))
    mis_shaped = sorted(k for k in set(own) & set(state) if own[k].shape != state[k].shape)
    if mis_shaped or (strict and (missing or unexpected)):
        raise ValueError(f"{path} does not match the {encoder.size!r} PointNetEncoder: missing {missing}, "
                         f"unexpected {unexpected}, wrong shape {mis_shaped}")
    encoder.load_state_dict(state, strict=strict)
    return encoder
