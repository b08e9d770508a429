"""The per-round curve (``rounds.png``) and ``report.md`` that ``dexart-lite distill`` writes."""

from __future__ import annotations

import os
import platform
from dataclasses import asdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dexart_lite.models.actor_critic import encoder_label  # noqa: E402
from dexart_lite.rl.evaluate import markdown_table  # noqa: E402


def plot_rounds(history: list[dict], evals: list[dict], path: Path, title: str = "") -> Path:
    """Success of the collection episodes per round (round 0: the noisy expert) with the final
    evaluation, and the training loss per round."""
    rounds = [h["round"] for h in history]
    fig, (ax_succ, ax_loss) = plt.subplots(1, 2, figsize=(9, 3.4))
    ax_succ.plot(rounds, [h["collect_success"] for h in history], marker="o", label="collection episodes")
    for e, color in zip(evals, ("tab:green", "tab:red")):
        ax_succ.axhline(e["success_rate"], color=color, linestyle="--", label=f"final eval, {e['split']}")
    ax_succ.set(xlabel="round (0: expert demonstrations)", ylabel="success rate", ylim=(-0.02, 1.02),
                title="success at any step")
    ax_succ.legend(fontsize=8)
    ax_loss.plot(rounds, [h["loss"] for h in history], marker="o", color="tab:orange")
    ax_loss.set(xlabel="round", ylabel="training loss (last epoch)", title="fit to the expert labels")
    for ax in (ax_succ, ax_loss):
        ax.grid(alpha=0.3)
        ax.set_xticks(rounds)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def write_report(path: Path, cfg, manifest: dict, history: list[dict], evals: list[dict],
                 curve: Path, wall_time_s: float, gif: str | None = None) -> Path:
    """``report.md`` of a run of ``cfg`` (a ``DistillConfig``): settings, one row per round, the curve
    and the evaluation table."""
    last = history[-1]
    lines = [
        f"# {cfg.method.upper()} student on {cfg.task} ({encoder_label(cfg.encoder)})", "",
        f"- expert frames {last['expert_frames']:,} ({len(manifest['episodes'])} demonstration episodes, executed-"
        f"action noise {manifest['noise']}, expert success {manifest['expert_success_rate']:.2f}); student frames "
        f"{last['student_frames']:,} in {len(history) - 1} DAgger rounds; buffer {last['buffer']:,} samples",
        f"- training: {cfg.loss} loss on the policy mean"
        + (f" + {cfg.aux_coef} x the auxiliary loss (the trunk predicts the privileged object state; the "
           f"logged loss is the sum)" if cfg.aux_coef > 0 else "")
        + f", Adam lr {cfg.lr}, batch {cfg.batch_size}, weight decay "
        f"{cfg.weight_decay}; {cfg.epochs} BC epochs, {cfg.epochs_per_round} per round",
        f"- wall time {wall_time_s / 60:.1f} min (collection, training, evaluation) on {platform.machine()}, "
        f"{cfg.threads or os.cpu_count()} torch threads for training", "",
        "## Rounds", "",
        "| round | phase | beta | episodes | success (collection) | mean max stage | expert-driven steps | "
        "new samples | buffer | loss first → last epoch | wall s |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for h in history:
        lines.append(f"| {h['round']} | {h['phase']} | {h['beta']:.3f} | {h['episodes']} | "
                     f"{h['collect_success']:.2f} | {h['collect_max_stage']:.2f} | {h['expert_share']:.2f} | "
                     f"{h['new_samples']:,} | {h['buffer']:,} | "
                     f"{h['loss_first']:.4f} → {h['loss']:.4f} | {h['wall_s']:.0f} |")
    lines += ["", "Round 0 is the expert with executed-action noise; later rounds execute the expert's action "
              "with probability beta, the student's deterministic action otherwise.", "",
              f"![success and loss per round]({curve.name})", ""]
    if evals:
        lines += ["## Evaluation (deterministic actions, success at any step)", "",
                  ", ".join(f"{e['split']}: **{e['success_rate']:.2f}** ({e['episodes']} episodes, "
                            f"{e['episodes_per_object']} per object, seed {e['seed']})" for e in evals), "",
                  markdown_table(evals), ""]
    if gif:
        lines += [f"![evaluation episode on an unseen object]({Path(gif).name})", ""]
    lines += ["## Configuration", "", "| field | value |", "|---|---|",
              *(f"| {k} | {v} |" for k, v in asdict(cfg).items()), ""]
    path.write_text("\n".join(lines))
    return path
