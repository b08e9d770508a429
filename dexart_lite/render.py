"""Save an episode as a GIF, with the stage and reward written on every frame.

    dexart-lite render --task laptop --policy scripted --out laptop.gif

``--policy`` is ``scripted`` (the privileged expert of ``dexart_lite.experts``), ``random``, or the path of
a PPO checkpoint (``dexart-lite train`` writes them).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

import dexart_lite
from dexart_lite.rollout import Policy, run_episodes
from dexart_lite.utils import check_choice


def annotate(frame: np.ndarray, lines: list[str]) -> Image.Image:
    """The frame (H, W, 3) uint8 with ``lines`` of text in its top-left corner."""
    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image)
    for i, line in enumerate(lines):
        draw.text((6, 4 + 12 * i), line, fill=(255, 255, 255), stroke_width=2, stroke_fill=(0, 0, 0))
    return image


def save_gif(frames: list[Image.Image], path: Path | str, fps: float = 12.5) -> Path:
    """Write PIL images as a looping GIF."""
    if not frames:
        raise ValueError("no frames to write")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)
    return path


def record_episode(env, policy: Policy, seed: int = 0, options: dict | None = None,
                   every: int = 2) -> tuple[list[Image.Image], dict]:
    """Run one episode of a ``render_mode="rgb_array"`` env (the rollout layer's loop) and return
    annotated frames (every ``every`` steps and the last) and a summary."""
    frames, so_far = [], {"return": 0.0, "success": False}

    def status(so_far: dict) -> str:  # the overlay's last line
        return f"return {so_far['return']:.2f}" + ("  SUCCESS" if so_far["success"] else "")

    def shoot(info: dict, t: int) -> None:
        frames.append(annotate(env.render(), [f"{info['object_name']}  t={t}",
                                              f"stage {info['stage']}  progress {info['progress']:.2f}",
                                              status(so_far)]))

    def on_step(obs, action, reward, next_obs, info, t):
        so_far["return"] += reward
        so_far["success"] = so_far["success"] or bool(info["success"])
        if (t + 1) % every == 0:
            shoot(info, t + 1)

    name = (options or {}).get("object")
    episode = run_episodes(policy, env, [(seed, name)], on_step=on_step,
                           on_reset=lambda obs, info: shoot(info, 0))[0]
    if episode["steps"] % every == 0:  # the last step's frame is replaced by the final one
        frames.pop()
    frames.append(annotate(env.render(), [f"{episode['object']}  t={episode['steps']}",
                                          f"stage {episode['stages'][-1]}", status(episode)]))
    return frames, {"return": episode["return"], "success": episode["success"], "steps": episode["steps"],
                    "object_name": episode["object"]}


def make_policy(name: str, env, seed: int = 0) -> Policy:
    """``scripted``, ``random`` or a checkpoint path -> a policy for ``env``."""
    if name == "scripted":
        from dexart_lite.experts import ScriptedPolicy

        return ScriptedPolicy(env)
    if name == "random":
        rng = np.random.default_rng(seed)
        return lambda obs: rng.uniform(-1, 1, 22)
    from dexart_lite.rl.checkpoint import checkpoint_path, load_policy

    path = checkpoint_path(name)  # zoo:<task>: a shipped policy
    if not path.exists():
        raise FileNotFoundError(f"--policy must be 'scripted', 'random', zoo:<task> or a checkpoint file; {name!r} "
                                f"is none of them")

    return load_policy(path, env)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, help=f"one of {', '.join(dexart_lite.TASKS)}")
    parser.add_argument("--policy", "--ckpt", default="scripted",
                        help="scripted, random, zoo:<task> (a shipped policy) or a checkpoint path")
    parser.add_argument("--split", default="seen")
    parser.add_argument("--object", help="object name (default: drawn by the seed)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True, help="GIF path")


def run(args: argparse.Namespace) -> int:
    from dexart_lite.envs import make

    check_choice("task", args.task, dexart_lite.TASKS)
    kwargs = {}
    from dexart_lite.rl.checkpoint import checkpoint_path, load_checkpoint, observation_kwargs

    if args.policy not in ("scripted", "random") and checkpoint_path(args.policy).is_file():  # its observation
        kwargs = {k: v for k, v in observation_kwargs(load_checkpoint(args.policy)).items() if k != "num_points"}
    env = make(args.task, split=args.split, render_mode="rgb_array", **kwargs)
    policy = make_policy(args.policy, env, args.seed)
    frames, summary = record_episode(env, policy, seed=args.seed,
                                     options={"object": args.object} if args.object else None)
    env.close()
    save_gif(frames, args.out)
    print(f"{args.out}: {summary['object_name']}, {summary['steps']} steps, return {summary['return']:.2f}, "
          f"success {summary['success']}")
    return 0
