"""Contracts of the off-policy learner (rl/sac.py, ``dexart-lite train --algo sac``): demonstration transitions,
the demonstration fraction of every batch, a checkpoint that resumes with its buffer and schedule and that
``dexart-lite eval`` loads, and bad values that name the valid choices."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import ExplorationType, set_exploration_type

from dexart_lite import cli
from dexart_lite.models.actor_critic import STATE_KEY
from dexart_lite.models.soft_actor_critic import make_sac_actor
from dexart_lite.rl import sac
from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint
from dexart_lite.rl.curriculum import guide_demos

def tiny(tmp_path, **overrides) -> sac.SACConfig:
    """A run of seconds: 2 batches of 60 frames, 30-step episodes, one demonstration per seen_half object."""
    return dataclasses.replace(sac.SACConfig(
        task="laptop", obs="state", split="seen_half", frames=120, frames_per_batch=60, warmup_frames=60, batch=16,
        utd=0.5, demo_episodes=1, max_episode_steps=30, eval_episodes=1, out=str(tmp_path / "run"), progress=False,
        checkpoint_every=1, threads=1, head="32,32", state_hidden=32, buffer=1000), **overrides)


@pytest.fixture(scope="module")
def demo_transitions():
    from dexart_lite import objects

    name = objects.list_objects("laptop", "seen")[0].name
    data, success = guide_demos("laptop", "seen", 2, 0.1, 0, {"observation": "state", "object_names": [name]},
                                transitions=True)
    return data, success


def test_demo_transitions_are_consecutive_steps_of_whole_episodes(demo_transitions):
    data, success = demo_transitions
    done = data["next", "done"].squeeze(-1)
    assert int(done.sum()) == 2 and bool(done[-1])  # one done per episode, on its last step
    inner = torch.nonzero(~done).squeeze(-1)
    assert torch.equal(data["next", "observation"][inner], data["observation"][inner + 1])
    terminated = data["next", "terminated"].squeeze(-1)
    assert not bool((terminated & ~done).any())  # success ends the episode (laptop terminates on success)
    assert int(terminated.sum()) == round(2 * success)
    # the executed action is the label plus the noise, clipped: close to the label, not equal to it
    gap = (data["action"] - data["expert_action"]).abs()
    assert 0.0 < float(gap.mean()) < 0.2 and float(data["action"].abs().max()) <= 1.0


@pytest.mark.parametrize("fraction", [0.0, 0.25, 0.5])
def test_batches_hold_the_demonstration_fraction_asked_for(demo_transitions, fraction):
    data, _ = demo_transitions
    keys = sac.transition_keys("none")
    online, demos = sac.make_buffer(1000), sac.make_buffer(len(data))
    sac.store(demos, data, keys, 0.01, demo=True)
    sac.store(online, data[:100], keys, 0.01, demo=False)
    for _ in range(3):
        batch = sac.mixed_batch(online, demos, 64, fraction)
        assert batch.numel() == 64
        assert int(batch["demo"].sum()) == round(64 * fraction)
    # the stored rewards are scaled, the demonstrations' and the online data's alike
    assert torch.allclose(demos[:5]["next", "reward"], data[:5]["next", "reward"] * 0.01)


def test_a_run_trains_saves_resumes_with_its_buffer_and_evaluates(tmp_path):
    cfg = tiny(tmp_path)
    first = sac.train(cfg)
    assert first["frames"] == 120
    rows = first["history"]
    assert [r["updates"] for r in rows] == [30, 30]  # utd 0.5 per frame once the 60 warm-up frames are in
    assert all(r["demo_share"] == 0.5 for r in rows)
    assert all(np.isfinite(r["loss_qvalue"]) for r in rows)
    payload = load_checkpoint(first["checkpoint"])
    assert payload["config"]["algo"] == "sac" and payload["buffer_saved"]
    # `dexart-lite eval` rebuilds the actor from the checkpoint: the same deterministic actions
    actor = actor_critic_from_checkpoint(payload)
    td = TensorDict({STATE_KEY: torch.randn(4, payload["dims"]["state_dim"])}, [4])
    trained = make_sac_actor(payload["dims"]["state_dim"], 22, "none", (32, 32), 32)
    trained.load_state_dict(payload["model"])
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        assert torch.equal(actor(td.clone())["action"], trained(td.clone())["action"])
    # resumed to 180 frames: counters, history and the online buffer (120 stored transitions) come back
    resumed = sac.train(dataclasses.replace(cfg, frames=180, resume=True))
    assert resumed["frames"] == 180 and len(resumed["history"]) == 3
    assert resumed["history"][-1]["buffer"] == 180  # 120 restored + 60 new
    assert cli.main(["eval", "--ckpt", resumed["checkpoint"], "--episodes-per-object", "1"]) == 0


def test_a_curriculum_run_keeps_its_schedule_across_resume(tmp_path):
    cfg = tiny(tmp_path, curriculum="uniform", curriculum_horizon=10, frames=60, eval_episodes=0)
    sac.train(cfg)
    assert load_checkpoint(tmp_path / "run" / "checkpoint.pt")["curriculum"]["config"]["horizon"] == 10
    with pytest.raises(ValueError, match="curriculum"):  # resumed under another schedule: refused, not mixed
        sac.train(dataclasses.replace(cfg, curriculum="none", frames=120, resume=True))


@pytest.mark.parametrize("overrides, message", [
    ({"demo_fraction": 1.5}, r"fraction in \[0, 1\]"),
    ({"demo_fraction": -0.1}, r"fraction in \[0, 1\]"),
    ({"demo_fraction": 0.5, "demo_episodes": 0}, "needs demonstrations"),
    ({"critics": 1}, "critics must be >= 2"),
    ({"curriculum": "backwards"}, "valid choices: none, uniform, reverse"),
    ({"curriculum": "uniform", "curriculum_horizon": -1}, "horizon H must be >= 0"),
    ({"guide": "nobody"}, "valid choices are 'expert'"),
    ({"obs": "pixels"}, "valid choices"),
    ({"utd": 0.0}, "utd"),
    ({"head": "wide"}, "comma-separated"),
])
def test_bad_values_name_the_problem(tmp_path, overrides, message):
    with pytest.raises(ValueError, match=message):
        sac.validate(tiny(tmp_path, **overrides))


def test_the_cli_names_the_algorithms_and_refuses_flags_of_the_other_learner(tmp_path, capsys):
    out = str(tmp_path / "x")
    assert cli.main(["train", "--algo", "td3", "--out", out]) == 2
    assert "valid choices: ppo, sac" in capsys.readouterr().err
    assert cli.main(["train", "--algo", "sac", "--epochs", "3", "--out", out]) == 2
    assert "--epochs: PPO options" in capsys.readouterr().err
    assert cli.main(["train", "--demo-fraction", "0.5", "--out", out]) == 2
    assert "--demo-fraction: SAC options" in capsys.readouterr().err


def test_the_curriculum_benchmark_runs_the_off_policy_recipes(tmp_path, load_benchmark):
    bench = load_benchmark("curriculum_runs")
    result = bench.main(["--task", "laptop", "--recipe", "sac_demos", "--seeds", "0", "--runs", str(tmp_path / "runs"),
                         "--results", str(tmp_path / "results")])  # fast mode (conftest): a smoke run
    assert result["settings"] == {"algo": "sac"} and result["preset"] == "SACConfig defaults"
    row, = result["per_seed"]
    assert row["frames"] == 200 and row["demo_frames"] > 0 and [c["frames"] for c in row["curve"]] == [100, 200]
    assert (tmp_path / "results" / "laptop_state_sac_demos.json").is_file()
