"""Trained policies shipped with the package: one point-cloud checkpoint per task, ``zoo:<task>``.

    dexart-lite eval --ckpt zoo:laptop --split unseen
    dexart-lite render --ckpt zoo:laptop --out laptop.gif

Every command that reads a checkpoint (``eval``, ``render``, ``train --init-from``, a curriculum's
``--guide``) accepts the spelling ``zoo:<task>``: ``dexart_lite.rl.checkpoint.load_checkpoint`` resolves it
here. ``manifest.json`` (beside this file) says, for each entry, how the policy was trained (command,
frames, seed, machine) and the seen / unseen success it was measured at, copied from the JSON that
``benchmarks/students/zoo_build.py`` wrote (``benchmarks/results/students/zoo.json``). Each file is <= 2 MB: the weights and
the run's config, without the optimizer.
"""

from __future__ import annotations

import json
from pathlib import Path

PREFIX = "zoo:"
FOLDER = Path(__file__).parent
MANIFEST = FOLDER / "manifest.json"
MAX_BYTES = 2 * 1024 * 1024  # per shipped checkpoint


def manifest() -> dict:
    """``{task: entry}`` of the shipped policies (``{}`` when none is shipped)."""
    return json.loads(MANIFEST.read_text())["policies"] if MANIFEST.exists() else {}


def is_zoo(spec) -> bool:
    return isinstance(spec, str) and spec.startswith(PREFIX)


def resolve(spec: str) -> Path:
    """The file of ``zoo:<name>``; a one-line error naming the valid entries when the name is unknown or its
    file is missing."""
    name = spec[len(PREFIX):]
    entries = manifest()
    valid = ", ".join(f"{PREFIX}{k}" for k in sorted(entries)) or "none shipped"
    if name not in entries:
        raise ValueError(f"unknown zoo policy {spec!r}; valid choices: {valid}")
    path = FOLDER / entries[name]["file"]
    if not path.is_file():
        raise FileNotFoundError(f"zoo policy {spec!r} is listed but its file {path.name} is missing from the "
                                f"installed package; valid choices: {valid}")
    return path
