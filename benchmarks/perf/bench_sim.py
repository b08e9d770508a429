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

``breakdown``: where one ``env.step`` of the registered env (gymnasium's wrappers included) goes, from
real steps: every piece the step loop calls is timed in place (exclusive of the pieces it calls
itself, so nothing is counted twice) and ``wrappers`` is the wrapped step minus the bare one, both
timed in the same rounds. ``step_glue`` is what the bare step spends outside the timed pieces
(``DexArtEnv.step``'s own lines). ``breakdown_sum_vs_full`` = the parts' sum over the wrapped step
measured without timers: the breakdown is complete when it is within 5 % of 1.

    python benchmarks/perf/bench_sim.py --task laptop --json benchmarks/results/perf/bench_sim.json
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections import defaultdict

import numpy as np

from dexart_lite import pointcloud as pc
from dexart_lite.envs import make
from dexart_lite.utils import provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")


class PartTimer:
    """Exclusive wall time per named piece of code, from wrappers put on bound methods in place."""

    def __init__(self):
        self.seconds: dict[str, float] = defaultdict(float)
        self._stack: list[list] = []  # [name, start, time spent in nested timed pieces]
        self._wrapped: list[tuple] = []  # (owner, attribute, its instance value or None)

    def wrap(self, owner, attribute: str, name: str) -> None:
        """Replace ``owner.attribute`` (a callable) by a timed call of it, as an instance attribute."""
        inner = getattr(owner, attribute)
        self._wrapped.append((owner, attribute, owner.__dict__.get(attribute)))

        def timed(*args, **kwargs):
            frame = [name, time.perf_counter(), 0.0]
            self._stack.append(frame)
            try:
                return inner(*args, **kwargs)
            finally:
                self._stack.pop()
                spent = time.perf_counter() - frame[1]
                self.seconds[name] += spent - frame[2]
                if self._stack:
                    self._stack[-1][2] += spent

        setattr(owner, attribute, timed)

    def restore(self) -> None:
        """Undo every ``wrap``: instance attributes come back, wrapped methods go."""
        for owner, attribute, value in reversed(self._wrapped):
            if value is None:
                del owner.__dict__[attribute]
            else:
                owner.__dict__[attribute] = value
        self._wrapped.clear()


# (object path from the bare env, method, part name); IK is the arm's twist -> joint velocity solve.
TIMED_PIECES = [
    ("", "_check_action", "check_action"),
    ("robot", "apply_action", "hand_motors"),
    ("robot", "twist_to_joint_velocity", "arm_ik"),
    ("robot", "track_arm", "arm_motors_per_substep"),
    ("sim", "step", "physics_substeps"),
    ("", "read_state", "state_read"),
    ("sim", "contact_forces", "contacts"),
    ("", "evaluate_state", "reward_and_info"),
    ("", "_observe", "state_vector"),
    ("sensor", "observe", "cloud_assembly"),
    ("sensor.camera", "render_depth", "render"),
    ("sensor.camera", "back_project", "back_project"),
    ("sensor", "labels", "labels"),
    ("sensor", "imagined_points", "imagine"),
]


def instrument(env, timer: PartTimer) -> None:
    """Put ``timer``'s wrappers on the pieces of ``env``'s step (again after a reset rebuilt the world)."""
    for path, method, name in TIMED_PIECES:
        owner = env
        for attribute in filter(None, path.split(".")):
            owner = getattr(owner, attribute)
        timer.wrap(owner, method, name)


def step_breakdown(task: str, actions: np.ndarray, rounds: int) -> dict:
    """Median ms per control step of each piece of ``env.step`` (see the module docstring)."""
    wrapped = make(task, point_noise=True, camera_noise=True)
    bare = wrapped.unwrapped
    per_round: dict[str, list[float]] = defaultdict(list)
    n = len(actions)
    for _ in range(rounds):
        for variant in ("wrapped", "bare", "timed"):
            wrapped.reset(seed=1)
            if variant == "timed":
                timer = PartTimer()
                instrument(bare, timer)
            step = wrapped.step if variant == "wrapped" else bare.step
            start = time.perf_counter()
            for a in actions:
                step(a)
            per_round[variant].append((time.perf_counter() - start) / n * 1e3)
            if variant == "timed":
                for name, seconds in timer.seconds.items():
                    per_round[name].append(seconds / n * 1e3)
                per_round["step_glue"].append(per_round["timed"][-1] - sum(timer.seconds.values()) / n * 1e3)
                timer.restore()
    wrapped.close()
    ms = {k: statistics.median(v) for k, v in per_round.items()}
    parts = {name: ms.get(name, 0.0) for _, _, name in TIMED_PIECES}
    parts["step_glue"] = ms["step_glue"]
    parts["wrappers"] = ms["wrapped"] - ms["bare"]
    return {"ms_per_step": parts, "wrapped_step_ms": ms["wrapped"], "bare_step_ms": ms["bare"],
            "timed_step_ms": ms["timed"], "breakdown_sum_vs_full": sum(parts.values()) / ms["wrapped"]}


def timed_parts(env, actions: np.ndarray, rng: np.random.Generator) -> dict:
    """The pieces of a control step, each a function that runs it once per action of ``actions`` (steps, 22):
    physics only, the full env step, the state snapshot, and the observation's stages on one rendered frame."""
    camera, sensor = env.sensor.camera, env.sensor

    def physics():
        for a in actions:
            q = env.state.robot.qpos
            env.robot.apply_action(a, q)
            for i in range(env.frame_skip):
                env.robot.track_arm((i + 1) * env.sim.dt)
                env.sim.step()

    def full():
        for a in actions:
            env.step(a)

    def snapshot():
        for _ in actions:
            state = env.read_state(np.zeros(22), env.state.robot.flange_pos, env.state.robot.palm_pos[2])
            env.evaluate_state(state)

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

    return {"physics": physics, "full": full, "snapshot": snapshot, "render": render,
            "back_project": back_project, "labels_crop": labels_crop, "sample": sample, "imagine": imagine}


def print_tables(result: dict) -> None:
    """The per-part and per-piece timings as markdown tables."""
    print(f"| part ({result['task']}) | ms per control step |\n|---|---|")
    for k, v in result["ms_per_step"].items():
        print(f"| {k} | {v:.3f} |")
    print(f"\nobs_overhead_ratio (full / physics) = {result['obs_overhead_ratio']:.2f}; "
          f"{result['steps_per_s_full']:.0f} env steps/s on one core")
    print(f"\n| piece of env.step ({result['task']}, wrapped) | ms per control step |\n|---|---|")
    for k, v in sorted(result["breakdown"]["ms_per_step"].items(), key=lambda kv: -kv[1]):
        print(f"| {k} | {v:.3f} |")
    print(f"| sum / wrapped step ({result['breakdown']['wrapped_step_ms']:.3f} ms) | {result['breakdown']['breakdown_sum_vs_full']:.3f} |")


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", "json", rounds=7, steps=40, helps={"steps": "control steps per part per round"})
    args = parser.parse_args(argv)

    env = make(args.task, point_noise=True, camera_noise=True).unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(args.steps, 22)) * np.r_[[0.2] * 6, [1.0] * 16]
    parts = timed_parts(env, actions, rng)
    times: dict[str, list[float]] = {k: [] for k in parts}
    for _ in range(args.rounds):
        for name, fn in parts.items():
            env.reset(seed=1)
            start = time.perf_counter()
            fn()
            times[name].append((time.perf_counter() - start) / args.steps * 1e3)
    env.close()
    ms = {k: statistics.median(v) for k, v in times.items()}
    breakdown = step_breakdown(args.task, actions, args.rounds)
    result = {
        "task": args.task,
        "ms_per_step": ms,
        "obs_overhead_ratio": ms["full"] / ms["physics"],
        "steps_per_s_full": 1e3 / ms["full"],
        "breakdown": breakdown,
        "settings": {"camera": "64x64 TinyRenderer", "points": "512 + 96", "dt": env.sim.dt, "frame_skip": env.frame_skip},
        **provenance(__file__, argv),
    }
    print_tables(result)
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
