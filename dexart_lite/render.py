"""Save an episode as a GIF, with the stage and reward written on every frame.

    dexart-lite render --task laptop --policy scripted --out laptop.gif

``--policy`` is ``scripted`` (the privileged expert of ``dexart_lite.experts``), ``random``, or the path of
a PPO checkpoint (``dexart-lite train`` writes them).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Callable

import numpy as np
from PIL import Image, ImageDraw

import dexart_lite
from dexart_lite.utils import check_choice

Policy = Callable[[dict], np.ndarray]  # observation -> action (22,)


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


def record_episode(env, policy: Policy, seed: int = 0, options: dict | None = None, every: int = 2,
                   max_steps: int | None = None) -> tuple[list[Image.Image], dict]:
    """Run one episode of a ``render_mode="rgb_array"`` env; returns annotated frames and a summary."""
    obs, info = env.reset(seed=seed, options=options)
    frames, total, success, step = [], 0.0, False, 0
    done = False
    while not done and (max_steps is None or step < max_steps):
        if step % every == 0:
            frames.append(annotate(env.render(), [f"{info['object_name']}  t={step}",
                                                  f"stage {info['stage']}  progress {info['progress']:.2f}",
                                                  f"return {total:.2f}" + ("  SUCCESS" if success else "")]))
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total, success, step = total + reward, success or info["success"], step + 1
        done = terminated or truncated
    frames.append(annotate(env.render(), [f"{info['object_name']}  t={step}", f"stage {info['stage']}",
                                          f"return {total:.2f}" + ("  SUCCESS" if success else "")]))
    return frames, {"return": total, "success": success, "steps": step, "object_name": info["object_name"]}


def make_policy(name: str, env, seed: int = 0) -> Policy:
    """``scripted``, ``random`` or a checkpoint path -> a policy for ``env``."""
    if name == "scripted":
        from dexart_lite.experts import ScriptedPolicy

        return ScriptedPolicy(env)
    if name == "random":
        rng = np.random.default_rng(seed)
        return lambda obs: rng.uniform(-1, 1, 22)
    path = Path(name)
    if not path.exists():
        raise FileNotFoundError(f"--policy must be 'scripted', 'random' or a checkpoint file; {name!r} is neither")
    from dexart_lite.rl.checkpoint import load_policy

    return load_policy(path, env)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--task", required=True, help=f"one of {', '.join(dexart_lite.TASKS)}")
    parser.add_argument("--policy", default="scripted", help="scripted, random, or a checkpoint path")
    parser.add_argument("--split", default="seen")
    parser.add_argument("--object", help="object name (default: drawn by the seed)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, required=True, help="GIF path")


def run(args: argparse.Namespace) -> int:
    from dexart_lite.envs import make

    check_choice("task", args.task, dexart_lite.TASKS)
    kwargs = {}
    if args.policy not in ("scripted", "random") and Path(args.policy).is_file():  # a checkpoint: its observation
        from dexart_lite.rl.checkpoint import load_checkpoint, observation_kwargs

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
