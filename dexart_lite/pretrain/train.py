"""Pretraining of the ``PointNetEncoder``: ``PretrainConfig`` and ``train(cfg)``.

    dexart-lite data dam --task laptop --out data/dam_laptop
    dexart-lite pretrain --method seg --data data/dam_laptop --out runs/pretrain/seg_laptop
    dexart-lite train --task laptop --pretrained runs/pretrain/seg_laptop/encoder.pt

Four methods (``METHODS``), DexArt's ``examples/pretrain`` recipes:

* ``seg``: per-point part segmentation (DAM: functional part, rest of the object, hand, arm;
  objects-only: functional part, rest), cross-entropy on logits with optional class weights.
  Metrics: mIoU and per-class IoU.
* ``cls``: category classification on the objects-only set. Metric: accuracy (and per template
  on unseen objects: template C is held out entirely).
* ``recon``: PCN reconstruction of the input cloud from the global feature, DexArt's Chamfer loss.
  Metric: symmetric Chamfer distance of the fine points (mm).
* ``simsiam``: two augmented views (jitter, point dropout, rotation about z), predictor,
  stop-gradient, symmetric negative cosine. Metric: k-NN accuracy on categories (objects-only data)
  or on the object instance (DAM, one category; validation only, the test objects are new).

``train`` reads top to bottom: data -> encoder + head -> Adam -> epochs of shuffled minibatches,
validation after each epoch -> final validation and test metrics -> ``encoder.pt`` (encoder-only
weights, ``save_encoder``; load with ``--pretrained``), ``head.pt``, ``curves.csv``,
``curves.png`` and ``metrics.json`` in ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
import torch.nn.functional as F
from torch import nn
from tqdm import tqdm

from dexart_lite.models.pointnet import ENCODER_SIZES, PointNetEncoder, save_encoder
from dexart_lite.pretrain import data as datasets
from dexart_lite.pretrain.heads import ClassificationHead, PCNDecoder, SegmentationHead, SimSiamPredictor
from dexart_lite.pretrain.losses import (chamfer_distance, confusion_matrix, iou_from_confusion,
                                         reconstruction_loss, simsiam_loss)
from dexart_lite.utils import DEVICES, check_choice, resolve_device

METHODS = ("seg", "cls", "recon", "simsiam")
BATCH_SIZE = {"seg": 32, "cls": 32, "recon": 64, "simsiam": 64}  # DexArt's (cls: none released)
MAIN_METRIC = {"seg": "miou", "cls": "accuracy", "recon": "chamfer_mm", "simsiam": "knn_accuracy"}
HEAD_FORMAT = "dexart_lite.pretrain.head"
EVAL_BATCH = 64  # clouds per forward pass when evaluating
KNN_K = 5  # SimSiam k-NN probe: neighbours (cosine similarity), majority vote
KNN_BANK = 4000  # at most this many training clouds in the k-NN memory bank
# SimSiam augmentations (DexArt: jitter 0.01, 50 % of the points zeroed, rotation U[0, 2 pi) about z)
JITTER_STD = 0.01  # m
DROPOUT = 0.5  # fraction of points replaced
ROTATION = 2 * math.pi  # rad, rotation about the vertical axis through the cloud's centroid


@dataclass
class PretrainConfig:
    """One pretraining run. Defaults: DexArt's optimiser and batch size, epochs sized for a CPU."""

    method: str = field(default="seg", metadata={"help": f"one of {', '.join(METHODS)}"})
    data: str = field(default="data/dam", metadata={"help": "dataset folder of `dexart-lite data`"})
    out: str = field(default="runs/pretrain", metadata={"help": "output folder (encoder.pt, curves, metrics)"})
    encoder: str = field(default="small", metadata={"help": "PointNet size: small, medium, large"})
    epochs: int = field(default=10, metadata={"help": "passes over the training set (DexArt: seg 100, recon 50, simsiam 30)"})
    batch_size: int = field(default=0, metadata={"help": "clouds per step; 0: DexArt's for the method (seg, cls 32; recon, simsiam 64)"})
    lr: float = field(default=1e-3, metadata={"help": "Adam learning rate, constant (DexArt)"})
    class_weights: str | None = field(default=None, metadata={"help": "seg: comma-separated cross-entropy weights per class (DexArt bucket: 3,1,1,1)"})
    max_steps: int = field(default=0, metadata={"help": "stop after this many steps (0: run all epochs); for quick checks"})
    max_train: int = field(default=0, metadata={"help": "use at most this many training clouds (0: all)"})
    recon_coarse: int = field(default=84, metadata={"help": "recon: coarse points (DexArt 84)"})
    recon_grid: int = field(default=2, metadata={"help": "recon: folding grid side; fine points = coarse x grid^2 (DexArt 4; 2 is 9x cheaper)"})
    recon_hidden: int = field(default=256, metadata={"help": "recon: folding MLP width (DexArt 512)"})
    seed: int = 0
    threads: int = field(default=0, metadata={"help": "torch threads (0: torch's default)"})
    device: str = field(default="cpu", metadata={"help": "where the encoder, head and optimizer live: cpu, cuda or "
                        "auto (cuda where there is one)"})
    progress: bool = field(default=True, metadata={"help": "show a progress bar"})


def validate(cfg: PretrainConfig) -> None:
    check_choice("method", cfg.method, METHODS)
    check_choice("encoder size", cfg.encoder, ENCODER_SIZES)
    check_choice("device", cfg.device, DEVICES)
    if cfg.device == "cuda":
        resolve_device(cfg.device)  # no CUDA here: one line, before any data is read
    if cfg.epochs < 1:
        raise ValueError(f"epochs must be >= 1, got {cfg.epochs}")
    if cfg.batch_size < 0 or cfg.max_steps < 0 or cfg.max_train < 0:
        raise ValueError("batch_size, max_steps and max_train must be >= 0")
    if cfg.class_weights and cfg.method != "seg":
        raise ValueError("class_weights apply to --method seg only")


def parse_class_weights(text: str | None, num_classes: int) -> torch.Tensor | None:
    if not text:
        return None
    try:
        weights = [float(w) for w in text.split(",")]
    except ValueError:
        raise ValueError(f"class_weights must be comma-separated numbers, got {text!r}") from None
    if len(weights) != num_classes or min(weights) < 0:
        raise ValueError(f"class_weights needs {num_classes} non-negative numbers (one per label), got {text!r}")
    return torch.tensor(weights)


# ----------------------------------------------------------------------------- method pieces
def make_head(cfg: PretrainConfig, num_labels: int) -> nn.Module:
    """The head of ``cfg.method``; ``num_labels``: the per-point classes of the data (seg)."""
    if cfg.method == "seg":
        return SegmentationHead(num_labels)
    if cfg.method == "cls":
        return ClassificationHead(len(datasets.objects_lib.CATEGORIES))
    if cfg.method == "recon":
        return PCNDecoder(coarse=cfg.recon_coarse, grid=cfg.recon_grid, fold_hidden=cfg.recon_hidden)
    return SimSiamPredictor()


def segment_logits(encoder: PointNetEncoder, head: SegmentationHead, points: torch.Tensor) -> torch.Tensor:
    """points (B, N, 3) -> per-point logits (B, N, classes)."""
    local = encoder.per_point(points)  # (B, N, 256)
    return head(local, local.max(dim=-2).values)


def simsiam_view(points: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """An augmented copy of points (B, N, 3): jitter, point dropout, rotation about z.

    Dropped points are replaced by copies of random kept ones (the cloud becomes a subset of
    itself); DexArt sets them to zero instead, which adds a fake point at the origin.
    """
    b, n, _ = points.shape  # the draws are made on the CPU (the generator's), then moved to the points' device
    view = points + torch.randn(points.shape, generator=generator).to(points.device) * JITTER_STD
    keep = (torch.rand(b, n, generator=generator) >= DROPOUT).to(points.device)  # (B, N)
    keep[:, 0] = True  # at least one point survives
    kept_first = torch.argsort((~keep).int(), dim=1, stable=True)  # (B, N): kept indices first, in order
    draw = torch.rand(b, n, generator=generator).to(points.device)
    pick = (draw * keep.sum(1, keepdim=True)).long()  # (B, N) r-th kept point
    source = torch.where(keep, torch.arange(n, device=points.device).expand(b, n),
                         torch.gather(kept_first, 1, pick))  # (B, N)
    view = torch.gather(view, 1, source[..., None].expand(-1, -1, 3))
    angle = torch.rand(b, 1, generator=generator).to(points.device) * ROTATION  # (B, 1) rad
    cos, sin = angle.cos(), angle.sin()
    centre = view.mean(dim=1, keepdim=True)  # (B, 1, 3)
    x, y = view[..., 0] - centre[..., 0], view[..., 1] - centre[..., 1]  # (B, N) each
    return torch.stack([cos * x - sin * y + centre[..., 0], sin * x + cos * y + centre[..., 1], view[..., 2]], dim=-1)


def batch_loss(method: str, encoder: PointNetEncoder, head: nn.Module, batch: dict, class_weights=None,
               generator: torch.Generator | None = None) -> tuple[torch.Tensor, object]:
    """The training loss (a scalar) of one minibatch and the head's output (seg, cls: logits;
    recon: (coarse, fine) points; simsiam: None). ``batch`` holds points (B, N, 3), labels (B, N)
    and category (B,)."""
    points = batch["points"]
    if method == "seg":
        logits = segment_logits(encoder, head, points)  # (B, N, classes)
        return F.cross_entropy(logits.flatten(0, 1), batch["labels"].flatten(), weight=class_weights), logits
    if method == "cls":
        logits = head(encoder(points))  # (B, categories)
        return F.cross_entropy(logits, batch["category"]), logits
    if method == "recon":
        coarse, fine = head(encoder(points))  # (B, K, 3), (B, F, 3)
        return reconstruction_loss(coarse, fine, points), (coarse, fine)
    z1, z2 = encoder(simsiam_view(points, generator)), encoder(simsiam_view(points, generator))  # (B, 256) each
    return simsiam_loss(head(z1), head(z2), z1, z2), None


def batches(data: datasets.PointCloudSet, size: int, order: torch.Tensor | None = None, device=None):
    """Minibatches of ``data`` as dicts, in ``order`` (default: as stored), on ``device`` (default: the CPU)."""
    order = torch.arange(len(data)) if order is None else order
    for index in order.split(size):
        batch = {"points": data.points[index], "labels": data.labels[index], "category": data.category[index],
                 "object": data.object_index[index]}
        yield {k: v.to(device) for k, v in batch.items()} if device is not None else batch


@torch.no_grad()
def encode_all(encoder: PointNetEncoder, data: datasets.PointCloudSet) -> torch.Tensor:
    """Global features (M, 256), on the CPU, of every cloud of ``data`` (computed where the encoder is)."""
    device = next(encoder.parameters()).device
    return torch.cat([encoder(b["points"]).cpu() for b in batches(data, EVAL_BATCH, device=device)])


def knn_accuracy(bank: torch.Tensor, bank_labels: torch.Tensor, query: torch.Tensor, labels: torch.Tensor) -> float:
    """Accuracy of a k-NN vote (cosine similarity, ``KNN_K`` neighbours) of ``query`` against ``bank``."""
    sim = F.normalize(query, dim=-1) @ F.normalize(bank, dim=-1).T  # (Q, M)
    neighbours = bank_labels[sim.topk(min(KNN_K, len(bank)), dim=-1).indices]  # (Q, k)
    return float((neighbours.mode(dim=-1).values == labels).float().mean())


@torch.no_grad()
def evaluate(method: str, encoder: PointNetEncoder, head: nn.Module, data: datasets.PointCloudSet,
             class_weights=None, bank: tuple | None = None) -> dict:
    """Loss and the metrics of ``method`` on ``data``. ``bank`` (SimSiam only): (features, labels)
    of training clouds for the k-NN probe; the probe's target is ``knn_target(data)``."""
    generator = torch.Generator().manual_seed(0)  # SimSiam's views: the same for every evaluation
    losses, sizes = [], []
    confusion = torch.zeros(data.num_classes, data.num_classes, dtype=torch.long)
    correct, chamfer = [], []
    device = next(encoder.parameters()).device  # the metrics are summed on the CPU
    for batch in batches(data, EVAL_BATCH, device=device):
        loss, output = batch_loss(method, encoder, head, batch, class_weights, generator)
        losses.append(float(loss))
        sizes.append(len(batch["points"]))
        if method == "seg":
            confusion += confusion_matrix(output.argmax(-1), batch["labels"], data.num_classes).cpu()
        elif method == "cls":
            correct.append((output.argmax(-1) == batch["category"]).cpu())
        elif method == "recon":
            chamfer.append(chamfer_distance(output[1], batch["points"]).cpu())
    metrics = {"clouds": len(data), "loss": sum(l * s for l, s in zip(losses, sizes)) / sum(sizes)}
    if method == "seg":
        iou = iou_from_confusion(confusion)
        metrics["miou"] = float(iou.nanmean())
        metrics["iou"] = {name: float(v) for name, v in zip(data.label_names, iou)}
        metrics["accuracy"] = float(confusion.diagonal().sum() / confusion.sum())
    elif method == "cls":
        hits = torch.cat(correct).float()
        metrics["accuracy"] = float(hits.mean())
        metrics["accuracy_by_template"] = {t: float(hits[data.template == i].mean())
                                           for i, t in enumerate("ABC") if (data.template == i).any()}
    elif method == "recon":
        metrics["chamfer_mm"] = 1000 * float(torch.cat(chamfer).mean())
    elif bank is not None:
        metrics["knn_target"] = knn_target(data)
        target = data.category if metrics["knn_target"] == "category" else data.object_index
        metrics["knn_accuracy"] = knn_accuracy(bank[0], bank[1], encode_all(encoder, data), target)
    return metrics


def knn_target(data: datasets.PointCloudSet) -> str:
    """What SimSiam's k-NN probe predicts: the category when there are several, else the object."""
    return "category" if len(data.category.unique()) > 1 else "object"


# ----------------------------------------------------------------------------- saving
def save_head(head: nn.Module, cfg: PretrainConfig, num_labels: int, path: Path) -> Path:
    """The head's weights and what rebuilds it (``load_head``)."""
    torch.save({"format": HEAD_FORMAT, "method": cfg.method, "num_labels": num_labels, "config": asdict(cfg),
                "state_dict": head.state_dict()}, path)
    return path


def load_head(path: str | Path) -> tuple[str, nn.Module]:
    """``(method, head)`` from a ``head.pt`` of ``train``, loaded strictly."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"head file not found: {path}")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:
        raise ValueError(f"{path} is not a readable head file ({type(err).__name__})") from None
    if not isinstance(payload, dict) or payload.get("format") != HEAD_FORMAT:
        raise ValueError(f"{path} is not a pretraining head written by dexart_lite.pretrain.train")
    cfg = PretrainConfig(**payload["config"])
    head = make_head(cfg, payload["num_labels"])
    head.load_state_dict(payload["state_dict"], strict=True)
    return payload["method"], head


def plot_curves(rows: list[dict], method: str, path: Path) -> Path:
    """Training and validation loss, and the validation metric, per epoch."""
    from matplotlib.figure import Figure

    metric = MAIN_METRIC[method]
    epochs = [r["epoch"] for r in rows]
    fig = Figure(figsize=(9, 3.4))
    ax_loss, ax_metric = fig.subplots(1, 2)
    ax_loss.plot(epochs, [r["train_loss"] for r in rows], marker=".", label="train")
    ax_loss.plot(epochs, [r["val_loss"] for r in rows], marker=".", label="validation")
    ax_loss.set(xlabel="epoch", ylabel="loss", title=f"{method} loss")
    ax_loss.legend()
    ax_metric.plot(epochs, [r[f"val_{metric}"] for r in rows], marker=".", color="tab:green")
    ax_metric.set(xlabel="epoch", ylabel=metric, title=f"validation {metric}")
    for ax in (ax_loss, ax_metric):
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    return path


# ----------------------------------------------------------------------------- training
def load_data(cfg: PretrainConfig, generator: torch.Generator) -> tuple:
    """Train and val clouds from seen objects, test clouds from unseen ones (None when not generated); at most
    ``cfg.max_train`` training clouds, drawn with ``generator``."""
    train_set = datasets.load_part(cfg.data, "train")
    val_set = datasets.load_part(cfg.data, "val")
    test_set = datasets.load_part(cfg.data, "test") if datasets.has_part(cfg.data, "test") else None
    if cfg.max_train and len(train_set) > cfg.max_train:
        train_set = train_set.subset(torch.randperm(len(train_set), generator=generator)[: cfg.max_train])
    if cfg.method == "cls" and len(train_set.category.unique()) < 2:
        raise ValueError(f"--method cls needs several categories: {cfg.data} holds one (use `dexart-lite data objects`)")
    return train_set, val_set, test_set


def knn_bank(cfg: PretrainConfig, encoder, train_set) -> tuple | None:
    """SimSiam's k-NN memory: the features of (at most KNN_BANK) training clouds and their targets; None for the
    other methods."""
    if cfg.method != "simsiam":
        return None
    subset = train_set.subset(torch.randperm(len(train_set), generator=torch.Generator().manual_seed(0))[:KNN_BANK])
    target = subset.category if knn_target(train_set) == "category" else subset.object_index
    return encode_all(encoder, subset), target


def append_row(path: Path, row: dict, header: bool) -> None:
    """One epoch's row of ``curves.csv``, written as the epoch ends (long runs can be watched)."""
    with path.open("a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(row))
        if header:
            writer.writeheader()
        writer.writerow(row)


def train(cfg: PretrainConfig) -> dict:
    """Pretrain, evaluate, save; returns the metrics and the paths of what was written."""
    validate(cfg)
    start = time.perf_counter()
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    generator = torch.Generator().manual_seed(cfg.seed)  # shuffling and SimSiam's augmentations

    train_set, val_set, test_set = load_data(cfg, generator)

    # ---- model: the one PointNetEncoder and the method's head
    device = resolve_device(cfg.device, log=tqdm.write)
    encoder = PointNetEncoder(cfg.encoder).to(device)
    head = make_head(cfg, train_set.num_classes).to(device)
    class_weights = parse_class_weights(cfg.class_weights, train_set.num_classes)
    class_weights = class_weights.to(device) if class_weights is not None else None
    optimizer = torch.optim.Adam([*encoder.parameters(), *head.parameters()], lr=cfg.lr)

    # ---- epochs of shuffled minibatches, validation after each
    out = Path(cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    batch_size = cfg.batch_size or BATCH_SIZE[cfg.method]
    steps_per_epoch = math.ceil(len(train_set) / batch_size)
    total = min(cfg.epochs * steps_per_epoch, cfg.max_steps or math.inf)
    bar = tqdm(total=total, unit="step", disable=not cfg.progress, dynamic_ncols=True, desc=f"pretrain {cfg.method}")
    csv_path = out / "curves.csv"  # one row per epoch, written as it ends (long runs can be watched)
    csv_path.unlink(missing_ok=True)
    rows, step = [], 0
    for epoch in range(1, cfg.epochs + 1):
        tick, loss_sum, seen = time.perf_counter(), 0.0, 0
        encoder.train(), head.train()
        order = torch.randperm(len(train_set), generator=generator)
        for batch in batches(train_set, batch_size, order, device if device.type != "cpu" else None):
            loss, _ = batch_loss(cfg.method, encoder, head, batch, class_weights, generator)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            value = float(loss.detach())
            loss_sum, seen, step = loss_sum + value * len(batch["points"]), seen + len(batch["points"]), step + 1
            bar.update(1)
            bar.set_postfix(loss=f"{value:.4f}")
            if step == cfg.max_steps:
                break
        train_seconds = time.perf_counter() - tick
        encoder.eval(), head.eval()
        val = evaluate(cfg.method, encoder, head, val_set, class_weights, knn_bank(cfg, encoder, train_set))
        metric = MAIN_METRIC[cfg.method]
        rows.append({"epoch": epoch, "steps": step, "clouds": seen, "train_loss": loss_sum / seen,
                     "val_loss": val["loss"], f"val_{metric}": val[metric], "train_seconds": train_seconds,
                     "wall_seconds": time.perf_counter() - start})
        append_row(csv_path, rows[-1], header=epoch == 1)
        if step == cfg.max_steps:
            break
    bar.close()

    # ---- final metrics on seen (validation, the last epoch's) and unseen (test) objects; files
    metrics = {"method": cfg.method, "encoder": cfg.encoder, "data": str(cfg.data), "kind": train_set.kind,
               "train_clouds": len(train_set), "epochs": len(rows), "steps": step,
               "seconds_per_epoch": sum(r["train_seconds"] for r in rows) / len(rows), "val": val}
    if test_set is not None:  # the k-NN probe on unseen objects only makes sense for categories
        metrics["test"] = evaluate(cfg.method, encoder, head, test_set, class_weights,
                                   knn_bank(cfg, encoder, train_set) if knn_target(train_set) == "category" else None)
    metrics["wall_seconds"] = time.perf_counter() - start
    metrics["config"], metrics["device"] = asdict(cfg), device.type
    encoder, head = encoder.cpu(), head.cpu()  # saved on the CPU: they load on any machine
    encoder_path = save_encoder(encoder, out / "encoder.pt")
    head_path = save_head(head, cfg, train_set.num_classes, out / "head.pt")
    png_path = plot_curves(rows, cfg.method, out / "curves.png")
    metrics_path = out / "metrics.json"
    metrics_path.write_text(json.dumps(metrics, indent=2) + "\n")
    return {"metrics": metrics, "history": rows, "encoder": str(encoder_path), "head": str(head_path),
            "curves_csv": str(csv_path), "curves_png": str(png_path), "metrics_json": str(metrics_path)}


# ----------------------------------------------------------------------------- command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from dexart_lite.cli import add_config_arguments

    add_config_arguments(parser, PretrainConfig)


def run(args: argparse.Namespace) -> int:
    from dexart_lite.cli import config_from_args

    result = train(config_from_args(PretrainConfig, args))
    metrics, metric = result["metrics"], MAIN_METRIC[result["metrics"]["method"]]
    for split in ("val", "test"):
        if split in metrics and metric in metrics[split]:
            print(f"{split} {metric}: {metrics[split][metric]:.4f} ({metrics[split]['clouds']} clouds)")
    print(f"encoder: {result['encoder']}\nmetrics: {result['metrics_json']}\ncurves:  {result['curves_png']}")
    return 0
