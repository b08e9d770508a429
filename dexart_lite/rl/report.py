"""The learning-curve PNG and ``report.md`` that ``dexart-lite train`` writes next to its checkpoint."""

from __future__ import annotations

import math
import platform
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dexart_lite.rl.evaluate import markdown_table  # noqa: E402
from dexart_lite.rl.learners import learner_name  # noqa: E402


def network_label(cfg: dict) -> str:
    """What the policy reads, for titles: "state MLP" (the state-only diagnostic) or "<size> PointNet"."""
    return "state MLP" if cfg.get("obs", "cloud") == "state" else f"{cfg['encoder']} PointNet"


def plot_curve(history: list[dict], path: str | Path, title: str = "") -> Path:
    """Episode return and episode success rate of the training batches against env frames."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [h for h in history if h.get("episodes", 0) > 0]  # batches in which at least one episode ended
    frames = [h["frames"] for h in rows]
    fig, (ax_ret, ax_succ) = plt.subplots(1, 2, figsize=(9, 3.4))
    ax_ret.plot(frames, [h["episode_return"] for h in rows], marker=".")
    ax_ret.set(xlabel="env frames", ylabel="mean episode return", title="return (training episodes)")
    ax_succ.plot(frames, [h["success_rate"] for h in rows], marker=".", color="tab:green")
    ax_succ.set(xlabel="env frames", ylabel="success rate", title="success at any step", ylim=(-0.02, 1.02))
    for ax in (ax_ret, ax_succ):
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _fmt(value: float, digits: int = 2) -> str:
    return "n/a" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}f}"


def write_report(path: str | Path, cfg: dict, history: list[dict], evals: list[dict], curve: Path,
                 wall_time_s: float, gif: str | None = None) -> Path:
    """A markdown report: command-line settings, throughput, learning curve, success table."""
    path = Path(path)
    last = history[-1] if history else {}
    collect = sum(h.get("collect_s", 0.0) for h in history)
    update = sum(h.get("update_s", 0.0) for h in history)
    frames = last.get("frames", 0)
    if learner_name(cfg) == "sac":
        algo = "SAC"
        settings = (f"- SAC: lr {cfg['lr']}, batch {cfg['batch']}, {cfg['utd']} updates per frame after "
                    f"{cfg['warmup_frames']:,} frames, {cfg['critics']} critics (LayerNorm: {cfg['layer_norm']}), tau "
                    f"{cfg['tau']}, gamma {cfg['gamma']}, rewards x {cfg['reward_scale']}; {cfg['demo_episodes']} "
                    f"demonstrations per object, {cfg['demo_fraction']:.0%} of every batch; curriculum "
                    f"{cfg['curriculum']}")
    else:
        algo = "PPO"
        settings = (f"- PPO: lr {cfg['lr']}, {cfg['epochs']} epochs, minibatch {cfg['minibatch']}, clip "
                    f"{cfg['clip_epsilon']}, gamma {cfg['gamma']}, lambda {cfg['lmbda']}, value coef {cfg['vf_coef']}, "
                    f"entropy coef {cfg['entropy_coef']}, grad norm {cfg['max_grad_norm']}; {cfg['workers']} collector "
                    f"workers ({cfg['backend']} backend); encoder {'frozen' if cfg['freeze_encoder'] else 'trained'}"
                    + (f", initialised from `{cfg['pretrained']}`" if cfg.get("pretrained") else ""))
    lines = [
        f"# {algo} on {cfg['task']} ({network_label(cfg)})", "",
        f"- frames: {frames:,} in {len(history)} batches of {cfg['frames_per_batch']:,}; wall time "
        f"{wall_time_s / 60:.1f} min (training, evaluation and report) on {platform.machine()}, "
        f"{cfg.get('threads') or 'all'} torch threads",
        settings,
        f"- throughput: collection {frames / collect if collect else float('nan'):.0f} frames/s "
        f"({collect:.0f} s), update {frames / update if update else float('nan'):.0f} frames/s ({update:.0f} s)",
        f"- last training batch: return {_fmt(last.get('episode_return'))}, success "
        f"{_fmt(last.get('success_rate'))}", "",
        f"![learning curve]({curve.name})", "",
    ]
    if evals:
        lines += ["## Evaluation (deterministic actions, success at any step)", "",
                  ", ".join(f"{e['split']}: **{e['success_rate']:.2f}** ({e['episodes']} episodes, "
                            f"{e['episodes_per_object']} per object, seed {e['seed']})" for e in evals), "",
                  markdown_table(evals), ""]
    if gif:
        lines += [f"![evaluation episode]({Path(gif).name})", ""]
    path.write_text("\n".join(lines))
    return path
