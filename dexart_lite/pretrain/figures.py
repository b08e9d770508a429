"""Pictures of segmentation results: true vs. predicted part labels of point clouds, in 3-D.

Uses matplotlib's ``Figure`` API only (no pyplot state), so it is safe in library code and in
worker processes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

# one colour per label of pointcloud.LABELS: functional part, rest of the object, hand, arm
LABEL_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#7f7f7f")


def plot_segmentation(points: list, true: list, pred: list, titles: list[str], label_names=None,
                      path: str | Path | None = None, point_size: float = 3.0):
    """One column per cloud: true labels on top, predicted below (the layout of DexArt's figure).

    Args:
        points: clouds, each (N, 3) m (numpy or torch).
        true, pred: per-point labels, each (N,) ints.
        titles: one per cloud (e.g. the object name and split).
        label_names: names for the legend (default: ``pointcloud.LABELS``).
        path: where to save a PNG (optional).

    Returns:
        the ``matplotlib.figure.Figure``.
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from dexart_lite import pointcloud as pc

    label_names = tuple(label_names or pc.LABELS)
    colours = np.array(LABEL_COLOURS)
    columns = len(points)
    fig = Figure(figsize=(3.2 * columns, 6.6))
    for c, (cloud, t, p, title) in enumerate(zip(points, true, pred, titles)):
        cloud = torch.as_tensor(cloud).numpy()
        t, p = torch.as_tensor(t).numpy(), torch.as_tensor(p).numpy()
        accuracy = float((t == p).mean())
        for r, (labels, name) in enumerate(((t, "true"), (p, f"predicted ({accuracy:.0%} of points right)"))):
            ax = fig.add_subplot(2, columns, r * columns + c + 1, projection="3d")
            ax.scatter(cloud[:, 0], cloud[:, 1], cloud[:, 2], c=colours[labels], s=point_size, depthshade=False)
            ax.set_title(f"{title}\n{name}", fontsize=8)
            ax.view_init(elev=25, azim=-150)
            ax.set_box_aspect(np.ptp(cloud, axis=0) + 1e-3)
            ax.tick_params(labelsize=5)
    handles = [Line2D([], [], marker="o", linestyle="", color=LABEL_COLOURS[i], label=n)
               for i, n in enumerate(label_names)]
    fig.legend(handles=handles, loc="lower center", ncol=len(label_names), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    return fig
