"""The 2-D baseline's encoder: a small CNN on the 64 x 64 depth image of the same camera as the cloud.

DexArt's viewpoint study (Sec. 5.3) contrasts its point-cloud policy with a policy on images: the
point cloud is expressed in the robot's frame whatever the camera's pose, an image is not. Here the
baseline is the same actor-critic with this encoder in place of the PointNet (``make_actor_critic(...,
encoder="depth_cnn")``), reading ``obs["depth_image"]`` (metres along the optical axis, 0 where the
ray hits nothing; the env's ``depth_image=True``).

    depth (..., 64, 64) -> conv 5x5/2 (16) -> conv 3x3/2 (32) -> conv 3x3/2 (64) -> conv 3x3/2 (64)
      -> (..., 64 * 4 * 4) -> Linear -> (..., 256), GELU between layers (as DexArt's PointNets)
"""

from __future__ import annotations

import torch
from torch import nn

from dexart_lite.models.pointnet import FEATURE_DIM

IMAGE_SIZE = 64  # px, DexArt's camera


class DepthCNN(nn.Module):
    """(..., 64, 64) depth images (m) -> (..., 256) features."""

    def __init__(self, out_dim: int = FEATURE_DIM):
        super().__init__()
        self.size = "depth_cnn"
        self.convs = nn.Sequential(
            nn.Conv2d(1, 16, 5, stride=2, padding=2), nn.GELU(),   # 32 x 32
            nn.Conv2d(16, 32, 3, stride=2, padding=1), nn.GELU(),  # 16 x 16
            nn.Conv2d(32, 64, 3, stride=2, padding=1), nn.GELU(),  # 8 x 8
            nn.Conv2d(64, 64, 3, stride=2, padding=1), nn.GELU(),  # 4 x 4
        )
        self.head = nn.Linear(64 * 4 * 4, out_dim)
        self.out_dim = out_dim

    def forward(self, depth: torch.Tensor) -> torch.Tensor:
        if depth.shape[-2:] != (IMAGE_SIZE, IMAGE_SIZE):
            raise ValueError(f"DepthCNN expects (..., {IMAGE_SIZE}, {IMAGE_SIZE}) images, got {tuple(depth.shape)}")
        lead = depth.shape[:-2]
        x = self.convs(depth.reshape(-1, 1, IMAGE_SIZE, IMAGE_SIZE))
        return self.head(x.flatten(1)).reshape(*lead, self.out_dim)
