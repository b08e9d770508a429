"""The heads that pretraining puts on the ``PointNetEncoder``; only the encoder is kept afterwards.

    SegmentationHead   per-point feature (B, N, 256) || global (B, 256) -> 128 -> GELU -> classes
    ClassificationHead global (B, 256) -> 128 -> GELU -> classes
    PCNDecoder         global (B, 256) -> coarse (B, 84, 3) -> folded fine (B, 84 * 16, 3)
    SimSiamPredictor   (B, 256) -> 256 -> GELU -> 256

Sizes follow DexArt's ``examples/pretrain`` (its segmentation, classification, PCN reconstruction and
SimSiam heads on the 256-D PointNet feature).
The heads output logits; losses live in ``losses.py``.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from dexart_lite.models.pointnet import FEATURE_DIM

HIDDEN = 128  # segmentation / classification hidden width (DexArt)


class SegmentationHead(nn.Module):
    """Per-point logits from each point's feature concatenated with the cloud's max-pooled feature.

    ``Linear(concat[local, global])`` is computed as ``W_local @ local + W_global @ global``: the same
    function and parameters, but the global half runs once per cloud instead of once per point.
    """

    def __init__(self, num_classes: int, feature_dim: int = FEATURE_DIM, hidden: int = HIDDEN):
        super().__init__()
        self.feature_dim = feature_dim
        self.fuse = nn.Linear(2 * feature_dim, hidden)  # input = [local, global]
        self.out = nn.Linear(hidden, num_classes)

    def forward(self, local: torch.Tensor, pooled: torch.Tensor) -> torch.Tensor:
        """local (B, N, C), pooled (B, C) -> logits (B, N, classes)."""
        w_local, w_global = self.fuse.weight.split(self.feature_dim, dim=1)  # (H, C) each
        hidden = F.linear(local, w_local) + F.linear(pooled, w_global, self.fuse.bias).unsqueeze(-2)  # (B, N, H)
        return self.out(F.gelu(hidden))


class ClassificationHead(nn.Module):
    """Cloud logits from the global feature."""

    def __init__(self, num_classes: int, feature_dim: int = FEATURE_DIM, hidden: int = HIDDEN):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(feature_dim, hidden), nn.GELU(), nn.Linear(hidden, num_classes))

    def forward(self, pooled: torch.Tensor) -> torch.Tensor:
        """pooled (B, C) -> logits (B, classes)."""
        return self.net(pooled)


class PCNDecoder(nn.Module):
    """PCN / OcCo decoder: an MLP predicts ``coarse`` points, then each is folded into a
    ``grid x grid`` patch by an MLP on [global feature, 2-D grid offset, coarse point], added to
    the coarse point.

    DexArt: 84 coarse points, 4 x 4 grid of half-width 0.05 m, widths 1024 and 512 (1344 fine points).
    """

    def __init__(self, feature_dim: int = FEATURE_DIM, coarse: int = 84, grid: int = 4, grid_scale: float = 0.05,
                 coarse_hidden: int = 1024, fold_hidden: int = 512):
        super().__init__()
        self.coarse, self.grid = coarse, grid
        self.coarse_mlp = nn.Sequential(nn.Linear(feature_dim, coarse_hidden), nn.ReLU(),
                                        nn.Linear(coarse_hidden, coarse_hidden), nn.ReLU(),
                                        nn.Linear(coarse_hidden, coarse * 3))
        self.fold_mlp = nn.Sequential(nn.Linear(feature_dim + 2 + 3, fold_hidden), nn.ReLU(),
                                      nn.Linear(fold_hidden, fold_hidden), nn.ReLU(),
                                      nn.Linear(fold_hidden, 3))
        side = torch.linspace(-grid_scale, grid_scale, grid)
        self.register_buffer("grid_offsets", torch.cartesian_prod(side, side), persistent=False)  # (G*G, 2) m

    @property
    def num_fine(self) -> int:
        return self.coarse * self.grid**2

    def forward(self, pooled: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """pooled (B, C) -> coarse (B, K, 3), fine (B, K * G * G, 3), m."""
        b, g2 = pooled.shape[0], self.grid**2
        coarse = self.coarse_mlp(pooled).reshape(b, self.coarse, 3)
        centres = coarse.repeat_interleave(g2, dim=1)  # (B, K*G2, 3): each coarse point G2 times
        offsets = self.grid_offsets.repeat(self.coarse, 1).expand(b, -1, -1)  # (B, K*G2, 2)
        features = pooled.unsqueeze(1).expand(-1, centres.shape[1], -1)  # (B, K*G2, C)
        fine = self.fold_mlp(torch.cat([features, offsets, centres], dim=-1)) + centres
        return coarse, fine


class SimSiamPredictor(nn.Module):
    """SimSiam's predictor MLP (DexArt: no projector, the encoder's feature is the embedding)."""

    def __init__(self, feature_dim: int = FEATURE_DIM, hidden: int = FEATURE_DIM):
        super().__init__()
        self.net = nn.Sequential(nn.Linear(feature_dim, hidden), nn.GELU(), nn.Linear(hidden, feature_dim))

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        """z (B, C) -> p (B, C)."""
        return self.net(z)
