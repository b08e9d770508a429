"""Contracts of the start-state curriculum (rl/curriculum.py) and of its use in PPO (rl/ppo.py)."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from functools import partial
from pathlib import Path

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from dexart_lite.envs import make
from dexart_lite.objects import list_objects
from dexart_lite.experts import ScriptedPolicy
from dexart_lite.rl import ppo
from dexart_lite.rl.curriculum import (Curriculum, CurriculumConfig, GuidedStart, find_demos, guide_demos, read_levels,
                                       send_level)
from dexart_lite.registration import HORIZON
from dexart_lite.rl.env import make_env

STATE = dict(observation="state")
CLOUD = dict(num_points=32)


def plain_run(kwargs: dict, seed: int, h: int, name: str | None = None) -> dict:
    """The observation after ``h`` expert steps of a plain env reset with ``seed``."""
    env = make("laptop", **kwargs)
    expert = ScriptedPolicy(env)
    obs, _ = env.reset(seed=seed, options={"object": name} if name else None)
    for _ in range(h):
        obs, *_ = env.step(expert(obs))
    env.close()
    return obs


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("kwargs", [STATE, CLOUD], ids=["state", "cloud"])
def test_h0_is_exactly_the_envs_own_reset(kwargs):
    plain = make("laptop", **kwargs)
    expected, info = plain.reset(seed=7)
    for level in ({"schedule": "none"}, {"schedule": "uniform", "horizon": 0}):
        env = GuidedStart(make("laptop", **kwargs), level)
        obs, got = env.start(7, 0) if level["schedule"] == "uniform" else env.reset(seed=7)
        assert same(obs, expected) and got["start_step"] == 0 and got["start_demo"] == -1
        assert got["object_name"] == info["object_name"] and env.guide_steps == 0
        # and the next steps are the env's too
        action = np.full(22, 0.3)
        assert same(env.step(action)[0], plain.step(action)[0])
        plain.reset(seed=7)


@pytest.mark.parametrize("kwargs", [STATE, CLOUD], ids=["state", "cloud"])
def test_first_observation_is_the_experts_after_h_steps_of_a_plain_run(kwargs):
    env = GuidedStart(make("laptop", **kwargs), {"schedule": "uniform", "horizon": 40}, guide_render=True)
    obs, info = env.start(3, 25)
    assert info["start_step"] == 25 and env.guide_steps == 25
    assert same(obs, plain_run(kwargs, 3, 25))
    assert env.unwrapped._t == 25  # the learner's episode goes on from the guide's step (its t / T included)


def test_skipping_the_guides_renders_keeps_the_physical_state():
    skip = GuidedStart(make("laptop", **CLOUD), {"schedule": "uniform", "horizon": 40}, guide_render=False)
    full = GuidedStart(make("laptop", **CLOUD), {"schedule": "uniform", "horizon": 40}, guide_render=True)
    a, b = skip.start(5, 30)[0], full.start(5, 30)[0]
    assert np.array_equal(a["state"], b["state"])  # same joints, palm, time
    assert a["point_cloud"].shape == b["point_cloud"].shape
    assert skip.unwrapped.observe_steps  # the learner's own steps observe again


def test_a_guide_that_succeeds_before_h_hands_over_one_step_before_its_success():
    (seed, name, length), = find_demos("laptop", 1, env_kwargs=STATE)
    env = GuidedStart(make("laptop", **STATE), {"schedule": "uniform", "horizon": 250})
    obs, info = env.start(seed, 249, name)
    assert info["start_step"] == length - 1 and not info["success"]
    assert same(obs, plain_run(STATE, seed, length - 1, name))


def test_on_a_task_that_goes_on_after_success_the_demo_length_is_the_first_success():
    # the bucket does not end at a success: L is where the guide first lifts it, not the horizon (250), so the
    # reverse frontier (L - 1) starts the learner before the lift, not after it
    (seed, name, length), = find_demos("bucket", 1, env_kwargs=STATE)
    assert 0 < length < HORIZON
    env = GuidedStart(make("bucket", **STATE), {"schedule": "none"})
    obs, info = env.start(seed, length - 1, name)
    assert info["start_step"] == length - 1 and not info["success"]
    assert env.step(env.guide(obs))[4]["success"]  # the guide's next step is its first success


def test_no_guide_step_is_collected_and_frames_count_the_learner_only():
    from torchrl.collectors import Collector

    from dexart_lite.models.actor_critic import Acting, make_actor_critic

    env = make_env("laptop", seed=0, level={"schedule": "uniform", "horizon": 15}, max_episode_steps=20, **STATE)
    policy = Acting(make_actor_critic(env.observation_spec["observation"].shape[-1], 22, "none"))
    collector = Collector(env, policy, frames_per_batch=60, total_frames=60)
    data = next(iter(collector))
    collector.shutdown()
    assert data.numel() == 60  # frames asked for = learner steps collected
    starts, counts = data["start_step"], data["step_count"].squeeze(-1)
    first = data["is_init"].squeeze(-1)
    assert (starts[first] > 0).any()  # guided episodes were collected ...
    # ... from the guide's last state on: the first collected observation's t / T is h / T, never earlier
    assert torch.allclose(data["observation"][first][:, 31], starts[first] / HORIZON)  # the time entry, t / 250
    assert (counts[first] == 0).all() and (starts + counts <= 20).all()  # no guide step in the episode


def test_a_level_set_by_the_trainer_reaches_every_worker_of_a_2_worker_collector():
    from torchrl.collectors import MultiSyncCollector

    from dexart_lite.models.actor_critic import Acting, make_actor_critic

    fns = [partial(make_env, "laptop", seed=i, max_episode_steps=90, **STATE) for i in range(2)]
    policy = Acting(make_actor_critic(47, 22, "none"))
    collector = MultiSyncCollector(fns, policy, frames_per_batch=200, total_frames=200)
    try:
        level = {"schedule": "reverse", "demos": [(1, "laptop_11cbb00f39", 120)], "frontiers": [77],
                 "true_resets": 0.0}
        assert read_levels(collector) == [{"schedule": "none"}] * 2
        send_level(collector, level)
        assert read_levels(collector) == [level, level]
        # the episode under way ends at step 90; each worker's next one starts at the frontier, 77 (+0..4)
        data = next(iter(collector))
        later = data["step_count"].squeeze(-1) < torch.arange(100)  # steps after the first reset
        assert ((data["start_step"] >= 77) & (data["start_step"] <= 81) | ~later).all()
        assert later[:, -1].all()  # both workers reached their second episode
    finally:
        collector.shutdown()


def batch(starts, demos, success) -> TensorDict:
    """A collector-like batch of one-step episodes: every step ends one."""
    n = len(starts)
    return TensorDict({"next": {"done": torch.ones(n, 1, dtype=torch.bool),
                                "start_step": torch.tensor(starts), "start_demo": torch.tensor(demos),
                                "episode_success": torch.tensor(success)}}, batch_size=[n])


def test_a_reverse_frontier_moves_back_after_k_successes_in_a_row_and_never_below_0():
    cfg = CurriculumConfig("reverse", demos=2, step=5, successes=3)
    cur = Curriculum(cfg, [(0, "a", 12), (1, "b", 30)])
    assert cur.frontiers.tolist() == [11, 29]  # one step before the guide's success
    cur.update(batch([11, 11], [0, 0], [True, True]))
    assert cur.frontiers.tolist() == [11, 29]  # 2 < k
    cur.update(batch([13, 11], [0, 0], [True, False]))  # a start past the frontier does not count; a failure resets
    assert cur.frontiers.tolist() == [11, 29] and cur.streaks.tolist() == [0, 0]
    stats = cur.update(batch([11, 11, 11, 0], [0, 0, 0, -1], [True, True, True, False]))
    assert cur.frontiers.tolist() == [6, 29]
    assert stats["success_frontier"] == 1.0 and stats["success_h0"] == 0.0 and stats["episodes_h0"] == 1
    # plain Python numbers: the history goes into checkpoints that load with weights_only=True
    assert all(type(v) in (int, float) for v in stats.values()), stats
    for _ in range(2):
        cur.update(batch([int(cur.frontiers[0])] * 3, [0] * 3, [True] * 3))
    assert cur.frontiers.tolist() == [0, 29]  # 6 -> 1 -> 0, not -4


def test_with_backoff_a_frontier_moves_forward_after_k_failures_in_a_row_and_never_past_the_guides_success():
    cur = Curriculum(CurriculumConfig("reverse", demos=1, step=5, successes=3, backoff=2), [(0, "a", 12)])
    cur.frontiers[:] = 3
    cur.update(batch([3, 3], [0, 0], [False, True]))  # a success resets the failure count
    assert cur.frontiers.tolist() == [3] and cur.failures.tolist() == [0]
    cur.update(batch([3, 4, 3], [0, 0, 0], [False, False, False]))  # the start past the frontier does not count
    assert cur.frontiers.tolist() == [8] and cur.failures.tolist() == [0]
    cur.update(batch([8, 8], [0, 0], [False, False]))
    assert cur.frontiers.tolist() == [11]  # 8 + 5 capped at L - 1 = 11
    rfcl = Curriculum(CurriculumConfig("reverse", demos=1), [(0, "a", 12)])  # backoff 0: failures never move it
    rfcl.update(batch([11] * 20, [0] * 20, [False] * 20))
    assert rfcl.frontiers.tolist() == [11]


def test_with_probes_a_success_before_the_frontier_moves_it_there_at_once():
    """--curriculum-probe: a frontier stuck where the learner fails (difficulty not monotone in h) moves back to an
    earlier start it succeeded from; failures there, and starts at or after the frontier, do not move it."""
    cur = Curriculum(CurriculumConfig("reverse", demos=2, successes=3, probe=0.2), [(0, "a", 40), (1, "b", 30)])
    cur.streaks[0] = 2
    stats = cur.update(batch([20, 12, 39, 25], [0, 0, 0, 1], [False, True, False, True]))
    assert cur.frontiers.tolist() == [12, 25] and cur.streaks.tolist() == [0, 0]  # 39 -> 12 (the success), 29 -> 25
    assert stats["episodes_probe"] == 3 and stats["success_probe"] == pytest.approx(2 / 3)
    cur.update(batch([5, 14], [0, 0], [False, True]))  # a failure before it, a success after it: no move
    assert cur.frontiers.tolist() == [12, 25]
    rfcl = Curriculum(CurriculumConfig("reverse", demos=1), [(0, "a", 40)])  # probe 0: RFCL, no jumps, no probe stats
    stats = rfcl.update(batch([10], [0], [True]))
    assert rfcl.frontiers.tolist() == [39] and "success_probe" not in stats


def test_probe_starts_are_uniform_before_the_frontier_at_their_rate():
    level = {"schedule": "reverse", "demos": [(0, "laptop_11cbb00f39", 200)], "frontiers": [100],
             "true_resets": 0.0, "probe": 0.3}
    env = GuidedStart(make("laptop", **STATE), level)
    env.reset(seed=0)
    h = np.array([env._draw(level)[2] for _ in range(3000)])
    early = h[h < 100]
    assert abs(len(early) / len(h) - 0.3) < 0.03 and set(h[h >= 100]) <= {100, 101, 102, 103, 104}
    assert early.min() < 10 and early.max() > 90 and abs(early.mean() - 49.5) < 4  # U{0, ..., 99}
    assert all(env._draw(dict(level, frontiers=[0]))[2] == 0 for _ in range(50))  # nothing before 0


def test_reverse_starts_are_drawn_just_after_the_frontier_and_true_resets_at_their_rate():
    level = {"schedule": "reverse", "demos": [(0, "laptop_11cbb00f39", 200)], "frontiers": [100],
             "true_resets": 0.25}
    env = GuidedStart(make("laptop", **STATE), level)
    env.reset(seed=0)
    draws = [env._draw(level) for _ in range(2000)]
    h = np.array([d[2] for d in draws])
    assert set(h) <= {0, 100, 101, 102, 103, 104}
    assert abs(np.mean(h == 0) - 0.25) < 0.04 and abs(np.mean(h == 100) - 0.75 * 0.5) < 0.04
    done = dict(level, frontiers=[0])  # every frontier at 0: the true reset only
    assert all(env._draw(done)[3] == -1 for _ in range(50))


def test_the_curriculum_state_round_trips_and_refuses_another_runs():
    cur = Curriculum(CurriculumConfig("reverse", demos=2), [(0, "a", 12), (1, "b", 30)])
    cur.update(batch([11] * 3, [0] * 3, [True] * 3))
    again = Curriculum(CurriculumConfig("reverse", demos=2), [(0, "a", 12), (1, "b", 30)])
    again.load_state_dict(cur.state_dict())
    assert again.frontiers.tolist() == cur.frontiers.tolist() == [6, 29]
    other = Curriculum(CurriculumConfig("reverse", demos=2, step=8), [(0, "a", 12), (1, "b", 30)])
    with pytest.raises(ValueError, match="does not match"):
        other.load_state_dict(cur.state_dict())
    # a checkpoint from before --curriculum-backoff existed (no "backoff", no "failures") resumes with backoff 0 ...
    old = cur.state_dict()
    del old["config"]["backoff"], old["config"]["probe"], old["failures"]
    again.load_state_dict(old)
    assert again.frontiers.tolist() == [6, 29] and again.failures.tolist() == [0, 0]
    backing = Curriculum(CurriculumConfig("reverse", demos=2, backoff=4), [(0, "a", 12), (1, "b", 30)])
    with pytest.raises(ValueError, match="does not match"):  # ... and not as a run that backs off
        backing.load_state_dict(old)


@pytest.mark.parametrize("field, value, message", [
    ("schedule", "backwards", "valid choices"), ("guide", "oracle", "valid choices"), ("horizon", -1, "H must be"),
    ("true_resets", 1.5, r"fraction in \[0, 1\]"), ("true_resets", -0.1, r"fraction in \[0, 1\]"),
    ("step", 0, "step must be >= 1"), ("backoff", -1, "backoff must be >= 0"),
    ("probe", 1.5, r"probe is a fraction in \[0, 1\]")])
def test_bad_curriculum_values_name_the_valid_ones(field, value, message):
    with pytest.raises(ValueError, match=message):
        CurriculumConfig(**{field: value}).validate()


def test_bad_curriculum_values_are_rejected_by_ppo_before_anything_starts(tmp_path):
    for overrides, message in [({"curriculum": "sideways"}, "valid choices"),
                               ({"curriculum_true_resets": 2.0}, "fraction"),
                               ({"curriculum": "uniform", "backend": "distributed"}, "process backend"),
                               ({"bc_warmstart": 5}, "needs --demo-episodes")]:
        with pytest.raises(ValueError, match=message):
            ppo.open_run(dataclasses.replace(ppo.PPOConfig(), out=str(tmp_path / "x"), **overrides))


def test_guide_demonstrations_are_labelled_by_the_clean_expert_and_reproducible():
    a, success = guide_demos("laptop", "seen", 1, 0.1, 3, {**STATE, "object_names": ["laptop_11cbb00f39"]})
    b, _ = guide_demos("laptop", "seen", 1, 0.1, 3, {**STATE, "object_names": ["laptop_11cbb00f39"]})
    assert set(a.keys()) == {"observation", "expert_action"} and success == 1.0
    assert torch.equal(a["observation"], b["observation"]) and torch.equal(a["expert_action"], b["expert_action"])
    # the first label is the expert's action on the reset observation of the same seed
    env = make("laptop", split="seen", object_names=["laptop_11cbb00f39"], point_noise=True, camera_noise=True, **STATE)
    obs, _ = env.reset(seed=3, options={"object": "laptop_11cbb00f39"})
    assert np.allclose(a["expert_action"][0].numpy(), ScriptedPolicy(env)(obs), atol=1e-6)


def test_bc_warmstart_fits_the_demonstrations():
    from dexart_lite.models.actor_critic import make_actor_critic
    from dexart_lite.rl.warmstart import bc_warmstart

    samples, _ = guide_demos("laptop", "seen", 1, 0.1, 0, {**STATE, "object_names": ["laptop_11cbb00f39"]})
    torch.manual_seed(0)
    net = make_actor_critic(samples["observation"].shape[-1], 22, "none", normalize=True)
    losses = bc_warmstart(net, samples, epochs=8, seed=0)
    assert losses[-1] < 0.5 * losses[0]


def test_a_curriculum_run_saves_and_resumes_its_schedule(tmp_path):
    cfg = dataclasses.replace(
        ppo.PPOConfig(), task="laptop", obs="state", workers=1, frames_per_batch=100, minibatch=100, epochs=1,
        frames=100, max_episode_steps=250, eval_episodes=0, progress=False, curriculum="reverse",
        curriculum_demos=2, demo_episodes=1, bc_warmstart=1, out=str(tmp_path / "run"),
        split="seen_half")
    first = ppo.train(cfg)
    saved = torch.load(tmp_path / "run" / ppo.CHECKPOINT, weights_only=False)["curriculum"]
    assert first["frames"] == 100 and first["demos"]["frames"] > 0
    assert len(saved["frontiers"]) == 2 and "start_mean" in first["history"][0]
    saved["frontiers"] = [3, 4]  # as if the run had walked them back: the resumed run must start from these
    payload = torch.load(tmp_path / "run" / ppo.CHECKPOINT, weights_only=False)
    payload["curriculum"] = saved
    torch.save(payload, tmp_path / "run" / ppo.CHECKPOINT)
    second = ppo.train(dataclasses.replace(cfg, frames=200, resume=True))
    assert second["frames"] == 200
    assert second["demos"]["frames"] == first["demos"]["frames"]  # the run's demonstration steps, counted once
    assert second["demos"]["bc_samples"] == first["demos"]["frames"]  # no DAgger rounds: the same demonstrations
    resumed = torch.load(tmp_path / "run" / ppo.CHECKPOINT, weights_only=False)["curriculum"]
    assert all(f <= s for f, s in zip(resumed["frontiers"], [3, 4]))


def test_in_a_dagger_round_the_driver_acts_and_the_guide_labels_what_it_visits():
    one = {**STATE, "object_names": ["laptop_11cbb00f39"], "max_episode_steps": 6}
    samples, success = guide_demos("laptop", "seen", 1, 0.0, 3, one, driver=lambda obs: np.zeros(22))
    env = make("laptop", split="seen", point_noise=True, camera_noise=True, **one)
    expert = ScriptedPolicy(env)
    obs, _ = env.reset(seed=3, options={"object": "laptop_11cbb00f39"})
    for t in range(6):  # the driver's path (action 0), with the expert asked on every state of it
        assert np.allclose(samples["observation"][t].numpy(), obs["state"])
        assert np.allclose(samples["expert_action"][t].numpy(), expert(obs), atol=1e-6)
        obs, *_ = env.step(np.zeros(22))
    assert len(samples) == 6 and success == 0.0


def test_a_checkpoint_can_be_the_guide(tmp_path):
    from dexart_lite.rl.env import make_env as torchrl_env

    cfg = dataclasses.replace(ppo.PPOConfig(), task="laptop", obs="state", out=str(tmp_path / "run"))
    learner = ppo.build_learner(cfg, partial(torchrl_env, "laptop", observation="state"))
    path = ppo.save(learner, cfg, tmp_path / "guide.pt", frames=0, batches=0, history=[])
    env = GuidedStart(make("laptop", **STATE), {"schedule": "uniform", "horizon": 10}, guide=str(path))
    obs, info = env.start(4, 6)
    plain = make("laptop", **STATE)
    expected, _ = plain.reset(seed=4)
    act = make_guide_policy(path)
    for _ in range(6):  # the checkpoint's deterministic actions, replayed by hand
        expected, *_ = plain.step(act(expected))
    assert info["start_step"] == 6 and same(obs, expected)


def make_guide_policy(path):
    from dexart_lite.rl.checkpoint import policy_function
    from dexart_lite.rl.evaluate import load_policy

    return policy_function(load_policy(path)[0])


def test_the_curriculum_benchmark_writes_the_fields_it_documents(tmp_path, load_benchmark):
    bench = load_benchmark("curriculum_runs")
    result = bench.main(["--task", "laptop", "--recipe", "reverse_bc", "--seeds", "0", "--runs", str(tmp_path / "runs"),
                         "--results", str(tmp_path / "results")])  # fast mode (conftest): a smoke run
    written = json.loads((tmp_path / "results" / "laptop_state_reverse_bc.json").read_text())
    assert written == json.loads(json.dumps(result))
    for key in ("task", "obs", "recipe", "frames", "demo_frames", "per_seed", "seen_success", "unseen_success",
                "command", "machine"):
        assert key in written, key
    row, = written["per_seed"]
    assert row["frames"] == 400 and row["demo_frames"] > 0 and row["curve"][0]["frames"] == 200
    assert {"seed", "seen_success", "unseen_success", "wall_time_s", "warmstart_success"} <= row.keys()
    assert {"stage3_frac", "update_steps_frac", "bc_weight"} <= row["curve"][0].keys()
    # --refresh-curves rebuilds the curves from the checkpoints alone (here: the same ones), trains nothing
    expected, written["per_seed"][0]["curve"] = row["curve"], []
    (tmp_path / "results" / "laptop_state_reverse_bc.json").write_text(json.dumps(written))
    refreshed = bench.main(["--task", "laptop", "--recipe", "reverse_bc", "--runs", str(tmp_path / "runs"),
                            "--results", str(tmp_path / "results"), "--refresh-curves"])
    assert refreshed["per_seed"][0]["curve"] == expected


def test_a_continued_curriculum_run_keeps_the_machines_of_its_earlier_parts(load_benchmark):
    """The JSON's ``machine`` is where the last part trained; a seed continued in this call puts the replaced JSON's
    machines before it (oldest first), a pure read-back leaves the replaced JSON's records as they were."""
    bench = load_benchmark("curriculum_runs")
    amd, xeon, here = {"cpu": "amd"}, {"cpu": "xeon"}, {"cpu": "here"}
    earlier = {"machine": xeon, "earlier_machines": [amd]}
    continued = {"resumed": True, "trained_in_this_call": True}
    read_back = {"resumed": True, "trained_in_this_call": False}
    fresh = {"resumed": False, "trained_in_this_call": True}
    assert bench.machine_records(here, earlier, [continued, read_back]) == {"machine": here,
                                                                             "earlier_machines": [amd, xeon]}
    assert bench.machine_records(here, earlier, [read_back, read_back]) == earlier
    assert bench.machine_records(here, {"machine": xeon}, [read_back]) == {"machine": xeon}
    assert bench.machine_records(here, earlier, [fresh]) == {"machine": here}  # trained from scratch here
    assert bench.machine_records(here, None, [continued]) == {"machine": here}


def test_the_curriculum_benchmarks_student_step_alone_distils_and_records_each_seed(tmp_path, load_benchmark):
    """--students-only: the student recipe's distillation without RL (fast mode: one object, one round), its
    success read from the student's own evaluation; a second call reads the finished student back, trains nothing;
    a recipe without a student is refused."""
    bench = load_benchmark("curriculum_runs")
    argv = ["--task", "laptop", "--obs", "cloud", "--recipe", "student_anchored", "--seeds", "0", "--students-only",
            "--runs", str(tmp_path / "runs"), "--results", str(tmp_path / "results")]
    result = bench.main(argv)
    written = json.loads((tmp_path / "results" / "laptop_cloud_student.json").read_text())
    assert written == json.loads(json.dumps(result))
    row, = written["per_seed"]
    student = tmp_path / "runs" / "laptop_cloud_student_s0"
    assert row["seen_success"] == json.loads((student / "eval_seen.json").read_text())["success_rate"]
    assert row["frames"] > 0 and row["wall_time_s"] > 0 and written["seen_success"] == row["seen_success"]
    assert written["student"]["task"] == "laptop" and {"command", "machine", "eval_seed"} <= written.keys()
    stamp = (student / "checkpoint.pt").stat().st_mtime_ns
    assert bench.main(argv)["per_seed"] == written["per_seed"]
    assert (student / "checkpoint.pt").stat().st_mtime_ns == stamp
    # a parked student (<results>/in_progress/<name>) missing from --runs is copied there and read back, not
    # distilled again
    (tmp_path / "results" / "in_progress").mkdir()
    shutil.move(student, tmp_path / "results" / "in_progress" / student.name)
    assert bench.main(argv)["per_seed"] == written["per_seed"]
    assert (student / "checkpoint.pt").stat().st_mtime_ns == stamp
    # --jobs 2: seeds in processes of their own, rows in seed order (seed 0 read back, seed 1 distilled)
    both = bench.main([*argv[:8], "1", "--jobs", "2", *argv[8:]])
    assert [r["seed"] for r in both["per_seed"]] == [0, 1] and both["per_seed"][0] == written["per_seed"][0]
    assert json.loads((tmp_path / "runs" / "laptop_cloud_student_s1" / "run.json").read_text())["config"]["seed"] == 1
    with pytest.raises(ValueError, match="student recipe"):
        bench.main([*argv[:5], "reverse_bc", *argv[6:]])


def test_parking_keeps_only_what_continues_an_unfinished_run_and_deletes_a_finished_one(tmp_path, load_benchmark):
    """Between sittings a run stopped short of its frames keeps its checkpoint and run.json, and its student's,
    under the one parked folder (no logs); once finished, its folder and its student's there are deleted."""
    from types import SimpleNamespace

    bench = load_benchmark("curriculum_runs")
    runs, committed = tmp_path / "runs", tmp_path / "in_progress"

    def run(name: str, frames: int, asked: int | None, init_from: str = "") -> SimpleNamespace:
        folder = runs / name
        (folder / "log" / "scalars").mkdir(parents=True)
        (folder / "log" / "scalars" / "loss.csv").write_text("step,value\n")
        (folder / "checkpoint.pt").write_bytes(b"weights")
        config = {**({"frames": asked} if asked is not None else {}), **({"init_from": init_from} if init_from else {})}
        (folder / "run.json").write_text(json.dumps({"frames": frames, "config": config}))
        return SimpleNamespace(out=str(folder), frames=asked)

    student = run("t_cloud_student_s0", 0, None)  # a student's config has no frames
    (runs / "t_cloud_student_s0" / "eval_seen.json").write_text("{}")
    rl = run("t_cloud_r_s0", 400, 1000, init_from=str(runs / "t_cloud_student_s0" / "checkpoint.pt"))
    # held-out evaluations (evaluate_many's cache): the student's of its checkpoint is kept; the RL run's is older
    # than its checkpoint (it was trained on since), so it measured another policy and stays behind
    (runs / "t_cloud_student_s0" / "heldout_seen_e10_seed1000.json").write_text("{}")
    stale = runs / "t_cloud_r_s0" / "heldout_seen_e10_seed1000.json"
    stale.write_text("{}")
    weights = (runs / "t_cloud_r_s0" / "checkpoint.pt").stat().st_mtime
    os.utime(stale, (weights - 60, weights - 60))
    assert bench.park([rl], [student], committed) == ["t_cloud_r_s0", "t_cloud_student_s0"]
    assert sorted(p.name for p in (committed / "t_cloud_r_s0").iterdir()) == ["checkpoint.pt", "run.json"]
    assert sorted(p.name for p in (committed / "t_cloud_student_s0").iterdir()) == [
        "checkpoint.pt", "eval_seen.json", "heldout_seen_e10_seed1000.json", "run.json"]
    # the run finishes in a later sitting: nothing of it, or of its student, stays parked
    (runs / "t_cloud_r_s0" / "run.json").write_text(json.dumps({"frames": 1000, "config": {"frames": 1000}}))
    assert bench.park([rl], [student], committed) == []
    assert list(committed.iterdir()) == []


def test_the_clone_capacity_benchmark_writes_the_fields_it_documents(tmp_path, load_benchmark):
    bench = load_benchmark("clone_capacity")
    path = tmp_path / "clone.json"
    result = bench.main(["--task", "laptop", "--arch", "wide", "--seeds", "0", "--rounds", "1", "--json", str(path)])
    assert json.loads(path.read_text()) == json.loads(json.dumps(result))
    row, = result["per_run"]
    assert row["arch"] == "wide" and row["head"] == "256,256" and row["state_hidden"] == 256
    assert len(row["dagger_success"]) == 1 and row["samples"] > 0
    assert {"seen_success", "unseen_success", "wall_time_s"} <= row.keys() and set(result["summary"]) == {"wide"}
    for key in ("command", "machine", "eval_episodes_per_object"):
        assert key in result


def test_value_error_at_the_switch_uses_the_discounted_return_of_complete_episodes():
    """Two trajectories of 6 steps, gamma 0.5, reward 1 per step. Trajectory 0: a guided episode (h = 5) ends at
    step 2 (G_0 = 1.75, V = 1.0 -> error 0.75), then an episode from the true reset that the batch cuts (not
    counted). Trajectory 1: an episode from the true reset ends at step 1 (G_0 = 1.5, V = 2.0 -> error 0.5)."""
    from tensordict import TensorDict

    from dexart_lite.rl.common import value_error_at_start

    done = torch.tensor([[0, 0, 1, 0, 0, 0], [0, 1, 0, 0, 0, 0]], dtype=torch.bool)
    first = torch.tensor([[1, 0, 0, 1, 0, 0], [1, 0, 1, 0, 0, 0]], dtype=torch.bool)
    start = torch.tensor([[5, 5, 5, 0, 0, 0], [0, 0, 3, 3, 3, 3]])
    value = torch.tensor([[1.0, 0, 0, 9, 0, 0], [2.0, 0, 9, 0, 0, 0]])
    data = TensorDict({"is_init": first[..., None], "state_value": value[..., None],
                       "next": {"reward": torch.ones(2, 6, 1), "done": done[..., None], "start_step": start}}, [2, 6])
    errors = value_error_at_start(data, 0.5)
    assert errors["value_error_guided"] == pytest.approx(0.75)
    assert errors["value_error_h0"] == pytest.approx(0.5)
    data["is_init"] = torch.zeros(2, 6, 1, dtype=torch.bool)  # no episode starts inside the batch
    assert value_error_at_start(data, 0.5) == {}  # nothing to measure: no key (never a NaN in the history)


def test_an_init_from_policy_drives_the_dagger_rounds_and_keeps_its_weights(tmp_path):
    """--init-from with --demo-episodes and --dagger-rounds (no --bc-warmstart): the loaded policy is not
    cloned again nor renormalised; the guide's demonstrations and the states the loaded policy visits, labelled
    by the guide, are the BC term's data."""
    one = dict(task="laptop", obs="state", out=str(tmp_path / "run"), max_episode_steps=20, split="seen_half")
    objects = len(list_objects("laptop", "seen_half"))
    env_fn = partial(make_env, "laptop", observation="state", max_episode_steps=20)
    source = ppo.build_learner(dataclasses.replace(ppo.PPOConfig(), **one, demo_episodes=1, bc_warmstart=2), env_fn)
    path = ppo.save(source, dataclasses.replace(ppo.PPOConfig(), **one), tmp_path / "student.pt", frames=0,
                    batches=0, history=[])
    cfg = dataclasses.replace(ppo.PPOConfig(), **one, init_from=str(path), demo_episodes=1, dagger_rounds=1,
                              bc_coef=1.0)
    learner = ppo.build_learner(cfg, env_fn)
    loaded, saved = learner.actor_critic.state_dict(), source.actor_critic.state_dict()
    assert all(torch.equal(loaded[k], saved[k]) for k in saved if "log_std" not in k)  # normalisation included
    assert learner.demos["warmstart_loss"] == [] and len(learner.demos["dagger_success"]) == 1
    # the suite runs in fast mode, where the guide's episodes are capped at the learner's 20 steps too
    guided, _ = guide_demos("laptop", "seen_half", 1, cfg.demo_noise, 10_000 + cfg.seed, cfg.env_kwargs())
    assert objects <= len(guided) <= objects * 20
    driven = len(learner.bc_data) - len(guided)  # one episode per object, the loaded policy driving
    assert torch.equal(learner.bc_data["expert_action"][:len(guided)], guided["expert_action"])
    assert len(learner.bc_data) == learner.demos["frames"] and objects <= driven <= objects * HORIZON
    with pytest.raises(ValueError, match="drop --bc-warmstart"):
        ppo.validate(dataclasses.replace(cfg, bc_warmstart=3))


def test_every_curriculum_recipe_builds_a_valid_config_and_the_capped_and_flat_ones_differ_in_the_reward_alone(
        load_benchmark, tmp_path):
    """Each recipe of benchmarks/rl/curriculum_runs.py is a config its learner accepts (validate raises on a bad
    field); the *_capped and *_flat recipes differ from their DexArt-reward twins in the reward alone."""
    from argparse import Namespace

    from dexart_lite.rl import ppo, sac

    bench = load_benchmark("curriculum_runs")
    # A clean checkout has no runs/: the recipes that start from a student checkpoint get an empty stand-in file
    # (validate only checks that it exists; nothing here loads it).
    args = Namespace(eval_episodes=1, max_minutes=None, jobs=1, runs=str(tmp_path), workers=1, device="cpu")
    configs = {}
    for recipe in bench.RECIPES:
        obs = "cloud" if bench.RECIPES[recipe].get("student") else "state"
        cfg = bench.config("faucet", obs, recipe, 0, 400, args)
        if getattr(cfg, "init_from", None):
            assert Path(cfg.init_from).is_relative_to(tmp_path)
            Path(cfg.init_from).parent.mkdir(parents=True, exist_ok=True)
            Path(cfg.init_from).touch()
        (sac if isinstance(cfg, sac.SACConfig) else ppo).validate(cfg)
        configs[recipe] = cfg
    assert configs["ppo"].reward == "dexart"
    for twin in ("dagger_wide", "student_anchored_release"):
        for mode in ("capped", "flat"):
            a, b = dataclasses.asdict(configs[f"{twin}_{mode}"]), dataclasses.asdict(configs[twin])
            assert a["reward"] == mode and b["reward"] == "dexart"
            assert {k for k in a if a[k] != b[k]} == {"reward", "out"}
    a, b = dataclasses.asdict(configs["dagger_wide_flat_g999"]), dataclasses.asdict(configs["dagger_wide_flat"])
    assert {k for k in a if a[k] != b[k]} == {"gamma", "out"} and (a["gamma"], b["gamma"]) == (0.999, 0.99)


def test_a_student_variant_recipe_starts_from_its_own_student_which_differs_from_the_headline_one_in_its_fields(
        load_benchmark, tmp_path):
    """student_erase_anchored_floor: its PPO config is student_anchored_floor's but for init_from, which names the
    erase student's folder; that student is the headline student's DistillConfig plus STUDENT_VARIANTS["erase"]."""
    from argparse import Namespace

    bench = load_benchmark("curriculum_runs")
    args = Namespace(eval_episodes=1, max_minutes=None, jobs=1, runs=str(tmp_path), workers=1, device="cpu")
    headline = dataclasses.asdict(bench.student_config("toilet", 0, args, "student_anchored_floor"))
    erase = dataclasses.asdict(bench.student_config("toilet", 0, args, "student_erase_anchored_floor"))
    changed = {k for k in headline if headline[k] != erase[k]}
    assert changed == {*bench.STUDENT_VARIANTS["erase"], "out"}
    assert all(erase[k] == v for k, v in bench.STUDENT_VARIANTS["erase"].items())
    assert Path(erase["out"]).name == "toilet_cloud_student_erase_s0"
    assert Path(headline["out"]).name == "toilet_cloud_student_s0"  # the committed students' folders keep their names
    floor = dataclasses.asdict(bench.config("toilet", "cloud", "student_anchored_floor", 0, 400, args))
    from_erase = dataclasses.asdict(bench.config("toilet", "cloud", "student_erase_anchored_floor", 0, 400, args))
    assert {k for k in floor if floor[k] != from_erase[k]} == {"init_from", "out"}
    assert from_erase["init_from"] == str(Path(erase["out"]) / "checkpoint.pt")
    wide = bench.config("toilet", "cloud", "student_erase_anchored_floor", 0, 400,
                        Namespace(**{**vars(args), "workers": 8, "device": "cuda"}))
    assert (wide.workers, wide.device) == (8, "cuda")  # --workers / --device reach the PPO config


def test_success_from_h_replays_the_demonstration_so_the_expert_still_succeeds_from_every_h(load_benchmark):
    """benchmarks/rl/success_from_h.py: the expert handed its own episode back after h steps (exact replay, the same
    expert instance going on) succeeds from every h, on every demonstration; --noise adds each std as a policy of its
    own (--noise-on: on part of the action); a policy that is neither expert nor label=checkpoint, or a negative std,
    is refused."""
    bench = load_benchmark("success_from_h")
    out = bench.main(["--task", "laptop", "--policy", "expert", "--demos", "1", "--h", "0", "60", "--noise", "0", "0.5"])
    demo, = out["demos"]
    assert demo[2] > 60  # the guide's first success comes after the largest h
    assert out["policies"]["expert"]["by_h"] == {"0": {"success": 1.0, "per_demo": [True]},
                                                 "60": {"success": 1.0, "per_demo": [True]}}
    noisy = out["policies"]["expert+noise0.5"]  # each policy at each --noise std, labelled with it
    assert noisy["noise"] == 0.5 and set(noisy["by_h"]) == {"0", "60"} and out["noise_on"] == "all"
    hand = bench.main(["--task", "laptop", "--policy", "expert", "--demos", "1", "--h", "60", "--noise", "0.5",
                       "--noise-on", "hand"])  # --noise-on: the part of the action it perturbs, in the label
    assert hand["noise_on"] == "hand" and list(hand["policies"]) == ["expert+noise0.5@hand"]
    with pytest.raises(SystemExit):
        bench.main(["--task", "laptop", "--policy", "student=no/such/checkpoint.pt"])
    with pytest.raises(ValueError, match="first success"):
        bench.main(["--task", "laptop", "--policy", "expert", "--demos", "1", "--h", "0", "400"])
    with pytest.raises(ValueError, match="--noise takes stds >= 0"):
        bench.main(["--task", "laptop", "--policy", "expert", "--noise", "0", "-0.1"])


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process tree from /proc (Linux)")
def test_kill_on_curriculum_runs_stops_its_seeds_and_leaves_no_worker_behind(tmp_path):
    """``kill`` (SIGTERM) on ``curriculum_runs.py --jobs 2`` ends it as Ctrl-C does, with one line and exit status
    130, and its two worker processes, each busy in a PPO run of 1M frames, end with it: a launcher stopped alone
    must not leave seeds training unwatched (their results would never reach the JSON)."""
    import os
    import sys

    from tests.processes import kill_once_started

    script = Path(__file__).resolve().parent.parent / "benchmarks" / "rl" / "curriculum_runs.py"
    env = {k: v for k, v in os.environ.items() if k != "DEXART_LITE_FAST"}  # fast mode would shrink the runs
    runs, stderr = tmp_path / "runs", tmp_path / "stderr.txt"
    status = kill_once_started(
        [sys.executable, str(script), "--task", "laptop", "--obs", "state", "--recipe", "ppo", "--seeds", "0", "1",
         "--jobs", "2", "--frames", "1000000", "--runs", str(runs), "--results", str(tmp_path / "results")],
        lambda pid: all((runs / f"laptop_state_ppo_s{seed}").exists() for seed in (0, 1)),  # both runs have started
        "curriculum_runs workers", stderr, env)
    assert status == 130
    text = stderr.read_text()
    assert any(line.startswith("curriculum_runs: interrupted") for line in text.splitlines())
    assert "Traceback" not in text
    assert not (tmp_path / "results").exists() or not any((tmp_path / "results").glob("*.json"))
