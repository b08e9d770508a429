"""Training curves of RL run sets side by side: the collected episodes' success, return, ... against online frames.

    python benchmarks/rl/curve_compare.py benchmarks/results/rl/curriculum/faucet_state_dagger_wide.json \
        benchmarks/results/rl/curriculum/faucet_state_dagger_wide_capped.json \
        benchmarks/results/rl/curriculum/faucet_state_dagger_wide_flat.json \
        --keys success_rate episode_return episode_length bc_weight \
        --png benchmarks/results/rl/faucet_state_reward_curves.png \
        --json benchmarks/results/rl/faucet_state_reward_curves.json

Reads the ``curve`` of every seed of each ``curriculum_runs.py`` JSON (nothing is trained or evaluated) and draws one
panel per ``--keys`` entry (default: success of the collected episodes, their mean return on the run's own reward,
the BC term's weight), a line per run set and seed, a running mean over ``--smooth`` batches, the frame axis from 0.
The table (printed, and in ``--json``) holds each key's mean over the batches inside each ``--windows`` span of
online frames, per run set (seeds pooled) and per seed.

Written to ``--json``: runs (per run set: file, task, obs, recipe, settings' reward, seeds), keys, windows, table
(rows: run, seed ("all" for the pooled row), window, then one mean per key; None where no batch falls in the window),
command, machine.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.cli import add_config_arguments
from dexart_lite.utils import provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")

DEFAULT_KEYS = ("success_rate", "episode_return", "bc_weight")
LABELS = {"success_rate": "success of the collected episodes", "episode_return": "mean episode return (own reward)",
          "bc_weight": "BC term weight", "anchor_weight": "anchor weight", "episode_length": "episode length (steps)",
          "kl_init": "KL to the initial policy (nats/step)", "frontier_mean": "mean start frontier (guide steps)",
          "success_h0": "success from the reset", "start_mean": "mean start (guide steps)"}


def frames_label(n: int) -> str:
    return f"{n // 1000}k" if n and n % 1000 == 0 else str(n)


def window_means(curve: list[dict], keys, windows: list[tuple[int, int]]) -> list[dict]:
    """Per ``(lo, hi)`` window of frames (lo < frames <= hi): the mean of each key over the batches in it (None
    where none, or where the key was never logged there)."""
    rows = []
    for lo, hi in windows:
        inside = [c for c in curve if lo < c["frames"] <= hi]
        row = {"window": f"{frames_label(lo)}-{frames_label(hi)}"}
        for key in keys:
            values = [v for v in (c.get(key) for c in inside) if v is not None and math.isfinite(v)]
            row[key] = float(np.mean(values)) if values else None
        rows.append(row)
    return rows


def label(result: dict) -> str:
    reward = result.get("settings", {}).get("reward", "dexart")
    return f"{result['task']} {result['obs']} {result['recipe']} (reward {reward})"


@dataclass
class Flags:
    """This script's own arguments; the shared ones come from the harness."""

    runs: list[Path] = field(default_factory=list, metadata={"positional": True,
                                                             "help": "curriculum_runs.py JSON files"})
    keys: list[str] = field(default_factory=lambda: list(DEFAULT_KEYS), metadata={"help": "curve fields to compare"})
    windows: list[int] = field(default_factory=lambda: [0, 300_000, 600_000, 1_000_000],
                               metadata={"help": "frame boundaries of the table's windows"})
    smooth: int = field(default=5, metadata={"min": 1, "help": "batches in the plotted running mean"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "png", "json")
    args = parser.parse_args(argv)
    if len(args.windows) < 2 or sorted(args.windows) != args.windows:
        raise ValueError(f"--windows needs at least two increasing frame counts, got {args.windows}")
    windows = list(zip(args.windows[:-1], args.windows[1:]))
    results = [json.loads(p.read_text()) for p in args.runs]
    for path, result in zip(args.runs, results):
        missing = {k for row in result["per_seed"] for k in args.keys if k not in row["curve"][0]}
        if missing:
            raise ValueError(f"{path} has no curve field {sorted(missing)} (refresh it: curriculum_runs.py "
                             f"--refresh-curves); its fields: {', '.join(result['per_seed'][0]['curve'][0])}")
    table = []
    for result in results:
        curves = {row["seed"]: row["curve"] for row in result["per_seed"]}
        pooled = [c for curve in curves.values() for c in curve]
        for seed, curve in [("all", pooled), *curves.items()]:
            table += [{"run": label(result), "seed": seed, **row} for row in window_means(curve, args.keys, windows)]
    fmt = lambda v: "-" if v is None else f"{v:.2f}"  # noqa: E731
    print("| run | seed | frames | " + " | ".join(args.keys) + " |\n|---|---|---|" + "---|" * len(args.keys))
    for row in table:
        print(f"| {row['run']} | {row['seed']} | {row['window']} | " + " | ".join(fmt(row[k]) for k in args.keys) + " |")
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, len(args.keys), figsize=(4.2 * len(args.keys), 3.2), squeeze=False)
        for i, result in enumerate(results):
            for row in result["per_seed"]:
                frames = np.array([c["frames"] for c in row["curve"]])
                for ax, key in zip(axes[0], args.keys):
                    values = np.array([np.nan if c[key] is None else c[key] for c in row["curve"]], dtype=float)
                    kernel = np.ones(min(args.smooth, len(values)))
                    valid = np.convolve(np.isfinite(values), kernel, "same")
                    smooth = np.convolve(np.nan_to_num(values), kernel, "same") / np.maximum(valid, 1)
                    ax.plot(frames, np.where(valid > 0, smooth, np.nan), color=f"C{i}",
                            linestyle="-" if row["seed"] == result["per_seed"][0]["seed"] else "--",
                            label=f"{label(result)} s{row['seed']}")
        for ax, key in zip(axes[0], args.keys):
            ax.set(xlabel="online frames", ylabel=LABELS.get(key, key), xlim=(0, None))
            ax.xaxis.set_major_formatter(lambda x, _pos: f"{x / 1e3:.0f}k")  # 300k, not 300000 run together
        axes[0][0].legend(fontsize=6)
        fig.tight_layout()
        args.png.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(args.png, dpi=110)
        plt.close(fig)
    summary = {"runs": [{"file": p.name, "task": r["task"], "obs": r["obs"], "recipe": r["recipe"],
                         "reward": r.get("settings", {}).get("reward", "dexart"),
                         "seeds": [row["seed"] for row in r["per_seed"]]} for p, r in zip(args.runs, results)],
               "keys": args.keys, "windows": args.windows, "table": table, **provenance(__file__, argv)}
    if args.json:
        write_json(args.json, summary)
    return summary


if __name__ == "__main__":
    main()
