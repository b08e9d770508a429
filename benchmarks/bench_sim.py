"""What an env step costs: physics alone against the full step with the point-cloud observation.

Measured side by side in one process, round-robin over repeated rounds (medians), so the ratios
hold even on a noisy machine:

* ``physics``: one control step without observation: action -> arm IK + motor targets -> frame_skip
  physics sub-steps;
* ``full``: ``env.step`` as training uses it (physics, state snapshot, reward, observation);
* the parts of the observation: ``render`` (TinyRenderer depth + segmentation), ``back_project``
  (depth -> world points), ``labels_crop`` (labels + crop box), ``sample`` (512 of them + noise),
  ``imagine`` (96 imagined hand points by forward kinematics), and ``snapshot`` (the state read,
  contacts and reward).

``obs_overhead_ratio`` = full step / physics-only step. Target at the defaults: <= 1.6.

    python benchmarks/bench_sim.py --task laptop --json benchmarks/results/bench_sim.json
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

import dexart_lite
from dexart_lite import pointcloud as pc
from dexart_lite.envs import make
from dexart_lite.utils import command_line, machine_info, write_json


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="laptop", choices=dexart_lite.TASKS)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--steps", type=int, default=40, help="control steps per part per round")
    parser.add_argument("--json", type=Path, help="write the results here")
    args = parser.parse_args(argv)

    env = make(args.task, point_noise=True, camera_noise=True).unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(args.steps, 22)) * np.r_[[0.2] * 6, [1.0] * 16]
    camera, sensor = env.sensor.camera, env.sensor

    def physics():
        for a in actions:
            q = env._state.robot.qpos
            env.robot.apply_action(a, q)
            for i in range(env.frame_skip):
                env.robot.track_arm((i + 1) * env.sim.dt)
                env.sim.step()

    def full():
        for a in actions:
            env.step(a)

    def snapshot():
        for _ in actions:
            state = env._read_state(np.zeros(22), env._state.robot.flange_pos, env._state.robot.palm_pos[2])
            env._evaluate(state)

    raw = camera.render_depth()
    world, seg = camera.back_project(*raw)

    def render():
        for _ in actions:
            camera.render_depth()

    def back_project():
        for _ in actions:
            camera.back_project(*raw)

    def labels_crop():
        for _ in actions:
            labels = sensor.labels(seg)
            (labels >= 0) & pc.crop_mask(world - sensor.robot_base, sensor.crop)

    points = world - sensor.robot_base

    def sample():
        for _ in actions:
            idx = pc.sample_indices(len(points), sensor.config.num_points, rng)
            pc.multiplicative_noise(points[idx], rng, sensor.config.point_noise_std)

    def imagine():
        for _ in actions:
            sensor.imagined_points()

    parts = {"physics": physics, "full": full, "snapshot": snapshot, "render": render,
             "back_project": back_project, "labels_crop": labels_crop, "sample": sample, "imagine": imagine}
    times: dict[str, list[float]] = {k: [] for k in parts}
    for _ in range(args.rounds):
        for name, fn in parts.items():
            env.reset(seed=1)
            start = time.perf_counter()
            fn()
            times[name].append((time.perf_counter() - start) / args.steps * 1e3)
    env.close()
    ms = {k: statistics.median(v) for k, v in times.items()}
    result = {
        "task": args.task,
        "ms_per_step": ms,
        "obs_overhead_ratio": ms["full"] / ms["physics"],
        "steps_per_s_full": 1e3 / ms["full"],
        "settings": {"camera": "64x64 TinyRenderer", "points": "512 + 96", "dt": env.sim.dt, "frame_skip": env.frame_skip},
        "command": command_line("benchmarks/bench_sim.py", argv),
        "machine": machine_info(),
    }
    print(f"| part ({args.task}) | ms per control step |\n|---|---|")
    for k, v in ms.items():
        print(f"| {k} | {v:.3f} |")
    print(f"\nobs_overhead_ratio (full / physics) = {result['obs_overhead_ratio']:.2f}; "
          f"{result['steps_per_s_full']:.0f} env steps/s on one core")
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
