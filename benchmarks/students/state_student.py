"""Diagnostic: can a student imitate the expert when it is *given* the object's state? (perception vs imitability)

    python benchmarks/students/state_student.py --task laptop --json benchmarks/results/students/state_student_laptop.json

The same DAgger loop as ``dexart-lite distill`` (noisy expert demonstrations, then rounds in which the
student drives with probability 1 - beta and the expert labels every visited state), but the student
is a plain MLP on the env's state vector plus the expert's privileged view of the object
(``experts.Solver.privileged``: part pose, joint angle and target, extent, grasp point), standardised
with the statistics of the data. No point cloud is involved (the env still renders one; it is
ignored). If this student succeeds where the point-cloud student fails, the expert is imitable and the
bottleneck is perception: reading the lid's pose and shape precisely from 608 points.

``--drop-failed`` and ``--beta-min`` are distill's ``drop_failed`` and ``beta_min``: the DAgger rounds keep only the
samples of their successful episodes, and the expert drives at least that share of the steps in every round.

Evaluation: deterministic actions, ``--eval-episodes`` per object on seen and unseen objects, env
seeds fixed. One seed per run (``--seed``); the JSON records the command and the machine.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field

import numpy as np
import torch

from dexart_lite.envs import make
from dexart_lite.demos import episode_list
from dexart_lite.rollout import noisy, per_object_summary, run_episodes
from dexart_lite.experts import ScriptedPolicy
from dexart_lite.cli import add_config_arguments
from dexart_lite.imitation.distill import DistillConfig, dagger_beta
from dexart_lite.utils import fast_mode, provenance, sibling_script, write_json

harness = sibling_script(__file__, "_harness")


class StateStudent(torch.nn.Module):
    """MLP (two hidden layers of 256) on [state vector, privileged object state], inputs standardised."""

    def __init__(self, in_dim: int, action_dim: int = 22):
        super().__init__()
        self.net = torch.nn.Sequential(torch.nn.Linear(in_dim, 256), torch.nn.ReLU(), torch.nn.Linear(256, 256),
                                       torch.nn.ReLU(), torch.nn.Linear(256, action_dim))
        self.register_buffer("mean", torch.zeros(in_dim))
        self.register_buffer("std", torch.ones(in_dim))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net((x - self.mean) / self.std)


class Driver:
    """The executed policy of one DAgger round: expert label on every step (kept with its input),
    the expert's action with probability ``beta``, the student's otherwise."""

    def __init__(self, expert: ScriptedPolicy, student: StateStudent, beta: float, noise: float,
                 rng: np.random.Generator):
        self.expert, self.student, self.beta, self.noise, self.rng = expert, student, beta, noise, rng
        self.inputs: list[np.ndarray] = []
        self.labels: list[np.ndarray] = []

    def __call__(self, obs: dict) -> np.ndarray:
        label = self.expert(obs)
        x = np.concatenate([obs["state"], self.expert.privileged]).astype(np.float32)
        self.inputs.append(x)
        self.labels.append(label.astype(np.float32))
        if self.rng.random() < self.beta:
            return np.clip(label + self.noise * self.rng.standard_normal(label.shape), -1.0, 1.0)
        with torch.no_grad():
            return self.student(torch.as_tensor(x)).clamp(-1.0, 1.0).numpy()


def fit(student: StateStudent, inputs: list, labels: list, steps: int, optimizer, generator) -> float:
    x, y = torch.as_tensor(np.stack(inputs)), torch.as_tensor(np.stack(labels))
    student.mean.copy_(x.mean(0))
    student.std.copy_(x.std(0).clamp_min(1e-3))
    for _ in range(steps):
        batch = torch.randint(len(y), (256,), generator=generator)
        loss = (student(x[batch]) - y[batch]).pow(2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return float(loss.detach())  # the last batch's MSE


@dataclass
class Flags:
    """This script's own flag; the student's settings come from DistillConfig, the shared ones from the harness."""

    steps: int = field(default=3000, metadata={"min": 1,
                                               "help": "Adam steps (batch 256) after the demos and each round"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    # the DAgger settings are distill's own fields, with its defaults
    add_config_arguments(parser, DistillConfig, names=["task", "demo_episodes_per_object", "demo_noise", "rounds",
                                                       "episodes_per_round", "beta", "beta_decay", "beta_min",
                                                       "drop_failed"], overrides=False)
    harness.options(parser, "seed")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "json", eval_episodes=2)
    args = parser.parse_args(argv)
    steps_per_episode = None
    if fast_mode():  # a smoke run of the script itself, not evidence
        args.rounds, args.steps, args.eval_episodes, args.demo_episodes_per_object = 1, 5, 1, 1
        steps_per_episode = 10
    start = time.perf_counter()
    torch.manual_seed(args.seed)
    torch.set_num_threads(1)
    rng, generator = np.random.default_rng([args.seed, 0]), torch.Generator().manual_seed(args.seed)
    env = make(args.task, split="seen", num_points=32, max_episode_steps=steps_per_episode)
    names = env.unwrapped.objects.names[:1] if fast_mode() else env.unwrapped.objects.names
    expert = ScriptedPolicy(env)
    student = StateStudent(env.observation_space["state"].shape[0] + 20)
    optimizer = torch.optim.Adam(student.parameters(), lr=1e-3)
    inputs, labels, history = [], [], []
    for r in range(args.rounds + 1):  # round 0: the demonstrations (the expert drives, with noise)
        beta = 1.0 if r == 0 else dagger_beta(args, r)  # distill's schedule (args has its three fields)
        driver = Driver(expert, student, beta, args.demo_noise if r == 0 else 0.0, rng)
        per = args.demo_episodes_per_object if r == 0 else args.episodes_per_round
        starts = []  # index of each episode's first sample in driver.inputs
        results = run_episodes(driver, env, episode_list(names, per, np.random.default_rng([args.seed, 1, r])),
                               on_reset=lambda obs, info: starts.append(len(driver.inputs)))
        keep = [(a, b) for a, b, result in zip(starts, starts[1:] + [len(driver.inputs)], results)
                if r == 0 or result["success"] or not args.drop_failed]
        inputs += [x for a, b in keep for x in driver.inputs[a:b]]
        labels += [y for a, b in keep for y in driver.labels[a:b]]
        loss = fit(student, inputs, labels, args.steps, optimizer, generator)
        history.append({"round": r, "beta": beta, "collect_success": per_object_summary(results)["success_rate"],
                        "kept_episodes": len(keep), "samples": len(labels), "loss": loss,
                        "wall_s": round(time.perf_counter() - start, 1)})
        print(history[-1], flush=True)
    env.close()
    evaluation = {}
    for split in ("seen", "unseen"):
        env = make(args.task, split=split, num_points=32, max_episode_steps=steps_per_episode)
        expert = ScriptedPolicy(env)  # only for the privileged input
        driver = Driver(expert, student, 0.0, 0.0, rng)
        split_names = env.unwrapped.objects.names[:1] if fast_mode() else env.unwrapped.objects.names
        results = run_episodes(driver, env, episode_list(split_names, args.eval_episodes,
                                                         np.random.default_rng([args.seed, 2])))
        evaluation[split] = per_object_summary(results)
        env.close()
        print(f"{split}: success {evaluation[split]['success_rate']:.2f}, "
              f"stage {evaluation[split]['mean_max_stage']:.2f}", flush=True)
    result = {"task": args.task, "seed": args.seed, "seen_success": evaluation["seen"]["success_rate"],
              "unseen_success": evaluation["unseen"]["success_rate"], "eval_episodes_per_object": args.eval_episodes,
              "history": history, "evaluation": evaluation, "wall_time_s": round(time.perf_counter() - start, 1),
              **provenance(__file__, argv)}
    if args.json:
        write_json(args.json, result)
    return result


if __name__ == "__main__":
    main()
