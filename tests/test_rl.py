"""The torchrl env, PPO training (tiny budgets), checkpoints, evaluation and the collection backends."""

import dataclasses
import importlib.util
import json
import math
import shutil
import socket
from functools import partial
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium import spaces
from tensordict import TensorDict
from torchrl.collectors import Collector
from torchrl.envs import check_env_specs
from torchrl.envs.utils import ExplorationType, set_exploration_type
from torchrl.objectives.value import GAE

from dexart_lite import cli
from dexart_lite import objects as objects_lib
from dexart_lite.models.actor_critic import encoder_of, make_actor_critic, set_action_log_std, trunk_of
from dexart_lite.models.pointnet import PointNetEncoder, save_encoder
from dexart_lite.rl import ppo
from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint
from dexart_lite.rl.env import EpisodeInfo, env_dims, make_env
from dexart_lite.rl.evaluate import evaluate
from dexart_lite.rl.warmstart import initial_weights
from dexart_lite.utils import release_freed_memory, resident_mb

# tiny: 32 observed points (+96 imagined), 20-step episodes, a few hundred frames per batch
TINY = dict(task="laptop", num_points=32, max_episode_steps=20, minibatch=200, epochs=2, eval_episodes=1,
            checkpoint_every=1, progress=False)


def tiny_config(tmp_path, **overrides) -> ppo.PPOConfig:
    return dataclasses.replace(ppo.PPOConfig(), **{**TINY, "out": str(tmp_path / "run"), **overrides})


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A 1,200-frame PPO run with 2 worker processes, evaluated on seen and unseen objects."""
    cfg = tiny_config(tmp_path_factory.mktemp("ppo"), frames=1200, frames_per_batch=600, workers=2)
    return cfg, ppo.train(cfg)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ------------------------------------------------------------------ env
def test_training_env_passes_check_env_specs():
    env = make_env("laptop", num_points=32, max_episode_steps=5)
    check_env_specs(env, seed=0)
    assert env_dims(env) == (32 + 96, 32, 22)
    rollout = env.rollout(8, break_when_any_done=False)
    assert rollout["next", "truncated"].squeeze(-1).tolist()[4]  # the 5-step time limit
    assert rollout["next", "stage"].min() >= 1 and rollout["next", "stage"].max() <= 3
    env.close()


class _Scripted(gym.Env):
    """Success at step 2 only, stages 1, 3, 2, ...: for the episode bookkeeping."""

    observation_space = spaces.Dict({"state": spaces.Box(-1, 1, (1,), np.float32)})
    action_space = spaces.Box(-1, 1, (1,), np.float32)

    def reset(self, *, seed=None, options=None):
        self.t = 0
        return {"state": np.zeros(1, np.float32)}, {"success": False, "stage": 1, "progress": 0.0}

    def step(self, action):
        self.t += 1
        info = {"success": self.t == 2, "stage": 3 if self.t == 2 else 2, "progress": 0.1 * self.t}
        return {"state": np.zeros(1, np.float32)}, 0.0, False, self.t >= 4, info


def test_episode_info_counts_success_at_any_step_and_the_highest_stage():
    env = EpisodeInfo(_Scripted())
    obs, info = env.reset()
    assert not info["episode_success"] and info["episode_max_stage"] == 1
    seen = [env.step(np.zeros(1))[-1] for _ in range(4)]
    assert [bool(i["success"]) for i in seen] == [False, True, False, False]
    assert [bool(i["episode_success"]) for i in seen] == [False, True, True, True]
    assert [int(i["episode_max_stage"]) for i in seen] == [2, 3, 3, 3]
    assert env.reset()[1]["episode_success"] == np.bool_(False)
    first, second = env.step(np.zeros(1))[0], env.step(np.zeros(1))[0]
    assert first is not second  # a new dict per step (torchrl edits the dict it receives)


def test_values_from_the_rollout_give_the_same_advantages_as_gae_with_a_value_network():
    torch.manual_seed(0)
    env = make_env("laptop", num_points=32, max_episode_steps=15)
    actor_critic = make_actor_critic(32, 22, "small")
    collector = Collector(env, actor_critic, frames_per_batch=40, total_frames=40)
    data = next(iter(collector))
    collector.shutdown()
    assert data["next", "truncated"].sum() == 2  # two time limits inside the batch
    reference = data.exclude("state_value").clone()  # the reference computes every value itself
    GAE(gamma=0.99, lmbda=0.95, value_network=actor_critic.get_value_operator())(reference)
    with torch.no_grad():
        ppo.add_next_values(data, actor_critic.get_value_operator())
        GAE(gamma=0.99, lmbda=0.95, value_network=None)(data)
    assert torch.allclose(data["advantage"], reference["advantage"], atol=1e-5)
    assert torch.allclose(data["value_target"], reference["value_target"], atol=1e-5)


def test_the_collectors_workers_act_with_the_learners_weights_after_each_update():
    """``make_collector`` hands the workers ``Acting(actor_critic)``: after the learner's weights change
    in place and ``update_policy_weights_()``, the 2 worker processes act with the new ones."""
    cfg = dataclasses.replace(ppo.PPOConfig(), task="laptop", workers=2, frames_per_batch=40)
    env_fn = partial(make_env, "laptop", num_points=32, max_episode_steps=20)
    actor_critic = make_actor_critic(32, 22, "small")
    collector = ppo.make_collector(cfg, [partial(env_fn, seed=i) for i in range(2)], actor_critic, total_frames=-1)
    try:
        batches = iter(collector)
        before = next(batches)
        with torch.no_grad():  # the learner's step, in place: every action 0.5, std e^-10
            action_layer = actor_critic.get_policy_head().module[0].module[0][-1]
            action_layer.weight.zero_()
            action_layer.bias.fill_(0.5)
            set_action_log_std(actor_critic, -10.0)
        collector.update_policy_weights_()
        after = next(batches)
    finally:
        collector.shutdown()
    assert before["action"].abs().mean() > 0.5  # std 1 before
    assert after.shape == (2, 20) and torch.allclose(after["action"], torch.full_like(after["action"], 0.5), atol=1e-3)
    assert torch.allclose(after["loc"], torch.full_like(after["loc"], 0.5))


# ------------------------------------------------------------------ config and CLI
def test_faithful_defaults_are_dexarts_ppo_settings():
    cfg = ppo.PPOConfig()
    assert (cfg.lr, cfg.gamma, cfg.lmbda, cfg.clip_epsilon, cfg.epochs, cfg.minibatch) == (1e-4, 0.99, 0.95, 0.2, 10, 500)
    assert (cfg.vf_coef, cfg.max_grad_norm, cfg.adam_eps, cfg.entropy_coef) == (0.5, 0.5, 1e-5, 0.0)
    assert cfg.normalize_advantage and cfg.frames_per_batch == 20_000 and cfg.encoder == "small"


def test_command_line_options_override_the_preset():
    parser = cli.argparse.ArgumentParser()
    ppo.add_arguments(parser)
    args = parser.parse_args(["--preset", "cpu", "--task", "bucket", "--frames", "5000", "--no-progress",
                              "--freeze-encoder", "--pretrained", "enc.pt", "--lr", "3e-4"])
    cfg = ppo.config_from_args(args)
    assert (cfg.task, cfg.frames, cfg.progress, cfg.freeze_encoder, cfg.pretrained, cfg.lr) == \
        ("bucket", 5000, False, True, "enc.pt", 3e-4)
    assert cfg.frames_per_batch == ppo.PRESETS["cpu"]["frames_per_batch"] and cfg.epochs == ppo.PRESETS["cpu"]["epochs"]


def test_every_config_command_takes_set_after_its_flags():
    """``--set FIELD=VALUE`` (the benchmarks' and study's spelling) on the commands built from a config: typed
    like the field, applied after the preset and the flags, and an unknown field is refused by name."""
    from dexart_lite.imitation.distill import DistillConfig
    from dexart_lite.rl import sac, train

    parser = cli.argparse.ArgumentParser()
    train.add_arguments(parser)
    args = parser.parse_args(["--preset", "cpu", "--epochs", "3", "--set", "epochs=7", "anchor_coef=0.5"])
    cfg = ppo.config_from_args(args)
    assert (cfg.epochs, cfg.anchor_coef, cfg.frames_per_batch) == (7, 0.5, ppo.PRESETS["cpu"]["frames_per_batch"])
    args = parser.parse_args(["--algo", "sac", "--set", "demo_fraction=0.25"])
    assert sac.config_from_args(args).demo_fraction == 0.25
    parser = cli.argparse.ArgumentParser()
    cli.add_config_arguments(parser, DistillConfig)
    cfg = cli.config_from_args(DistillConfig, parser.parse_args(["--rounds", "2", "--set", "rounds=5", "normalize=false"]))
    assert (cfg.rounds, cfg.normalize) == (5, False)
    with pytest.raises(ValueError, match="DistillConfig field.*'roundz'"):
        cli.config_from_args(DistillConfig, parser.parse_args(["--set", "roundz=5"]))


def test_a_required_config_flag_is_refused_when_missing_and_read_when_given(capsys):
    """``add_config_arguments(..., required=...)``: argparse refuses a command line without the flag (exit 2, the
    flag named), and a given one is typed like its field."""
    from dexart_lite.imitation.distill import DistillConfig

    parser = cli.argparse.ArgumentParser(prog="x")
    cli.add_config_arguments(parser, DistillConfig, names=["task", "rounds"], overrides=False, required=("rounds",))
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["--task", "bucket"])
    assert stop.value.code == 2 and "the following arguments are required: --rounds" in capsys.readouterr().err
    assert parser.parse_args(["--rounds", "3"]).rounds == 3 and parser.parse_args(["--rounds", "3"]).task == "laptop"


def test_a_config_flag_below_its_minimum_is_refused_by_name(capsys):
    """A field with ``metadata["min"]`` (the benchmarks' shared ``--jobs``, ``--eval-episodes``, ...): argparse
    refuses a smaller value, in one line naming the flag, and takes the minimum itself; a list field checks each."""
    from dataclasses import dataclass, field

    @dataclass
    class Settings:
        episodes: int = field(default=3, metadata={"min": 1})
        sigmas: list[float] = field(default_factory=lambda: [0.1], metadata={"min": 0.0})

    parser = cli.argparse.ArgumentParser(prog="x")
    cli.add_config_arguments(parser, Settings, overrides=False)
    for line, message in ((["--episodes", "0"], "argument --episodes: must be >= 1, got 0"),
                          (["--sigmas", "0.1", "-0.2"], "argument --sigmas: must be >= 0.0, got -0.2"),
                          (["--episodes", "two"], "argument --episodes: invalid int value: 'two'")):
        with pytest.raises(SystemExit) as stop:
            parser.parse_args(line)
        assert stop.value.code == 2 and message in capsys.readouterr().err
    args = parser.parse_args(["--episodes", "1", "--sigmas", "0", "0.3"])
    assert args.episodes == 1 and args.sigmas == [0.0, 0.3]


def test_a_config_field_can_be_positional_and_parsed_by_its_own_function(capsys):
    """``metadata["positional"]``: a list field is one or more positional values; ``metadata["parse"]`` converts
    each value (here ``SEED=PATH`` -> a pair), and its ``ValueError`` becomes argparse's one-line refusal."""
    from dataclasses import dataclass, field

    def pair(text: str) -> tuple[int, str]:
        seed, sep, path = text.partition("=")
        if not sep:
            raise ValueError(text)
        return int(seed), path

    @dataclass
    class Settings:
        checkpoints: list[tuple] = field(default_factory=list, metadata={"positional": True, "parse": pair})
        start: list[tuple] = field(default_factory=list, metadata={"parse": pair})

    parser = cli.argparse.ArgumentParser(prog="x")
    cli.add_config_arguments(parser, Settings, overrides=False)
    args = parser.parse_args(["0=a.pt", "1=b.pt", "--start", "0=s.pt"])
    assert args.checkpoints == [(0, "a.pt"), (1, "b.pt")] and args.start == [(0, "s.pt")]
    assert parser.parse_args(["0=a.pt"]).start == []
    for line, message in (([], "the following arguments are required: checkpoints"),
                          (["a.pt"], "argument checkpoints: invalid pair value: 'a.pt'")):
        with pytest.raises(SystemExit) as stop:
            parser.parse_args(line)
        assert stop.value.code == 2 and message in capsys.readouterr().err


def test_benchmark_flags_come_from_dataclasses():
    """Every benchmark script builds its flags from dataclass fields (``cli.add_config_arguments``, the harness's
    ``Options``); the three written by hand say why next to them: ``--set`` (bench_finetune: PPOConfig fields),
    ``--no-committed`` (curriculum_runs) and the repeated ``--policy`` (success_from_h)."""
    root = Path(__file__).resolve().parents[1] / "benchmarks"
    by_hand = {str(p.relative_to(root)): p.read_text().count(".add_argument(") for p in root.rglob("*.py")}
    assert {k: v for k, v in by_hand.items() if v} == {"rl/bench_finetune.py": 1, "rl/curriculum_runs.py": 1,
                                                       "rl/success_from_h.py": 1}


@pytest.mark.parametrize("overrides, message", [
    ({"encoder": "huge"}, "valid choices: small, medium, large"),
    ({"backend": "mpi"}, "valid choices: process, distributed, ray"),
    ({"frames_per_batch": 300, "minibatch": 100, "workers": 7}, "multiple of workers"),
    ({"frames_per_batch": 300, "minibatch": 200}, "must divide frames_per_batch"),
    ({"epochs": 0}, "epochs must be >= 1"),
    ({"init_log_std": float("nan")}, "init_log_std must be a finite number, got nan"),
    ({"obs_norm_steps": -1}, "obs_norm_steps must be >= 0, got -1"),
    ({"sil_coef": -1.0}, "sil_coef must be a finite number >= 0, got -1.0"),
    ({"sil_value_coef": float("inf")}, "sil_value_coef must be a finite number >= 0, got inf"),
    ({"sil_capacity": 0}, "sil_capacity must be >= 1 step, got 0"),
])
def test_bad_configs_are_rejected_before_anything_starts(tmp_path, overrides, message):
    with pytest.raises(ValueError, match=message):
        ppo.train(tiny_config(tmp_path, **overrides))


@pytest.mark.skipif(importlib.util.find_spec("ray") is not None, reason="ray is installed")
def test_ray_backend_without_ray_names_the_extra(tmp_path, capsys):
    code = cli.main(["train", "--backend", "ray", "--out", str(tmp_path / "r"), "--frames", "100"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "pip install '.[distributed]'" in err and len(err.splitlines()) == 1


# ------------------------------------------------------------------ training, checkpoint, evaluation
def test_tiny_run_gives_finite_losses_logs_and_a_report(tiny_run):
    cfg, result = tiny_run
    history = result["history"]
    assert [h["frames"] for h in history] == [600, 1200] and result["frames"] == 1200
    for row in history:
        for key in ppo.LOSS_KEYS + ("collect_fps", "update_fps", "log_std"):
            assert math.isfinite(row[key]), key
        assert row["episodes"] >= 1 and 0.0 <= row["success_rate"] <= 1.0
        assert abs(row["stage1_frac"] + row["stage2_frac"] + row["stage3_frac"] - 1.0) < 1e-5
        assert row["rss_mb"] > 50  # this process's resident memory after the batch (torch alone is more)
    out = result["log_dir"]
    for name in ("episode_return", "success_rate", "loss_objective", "kl_approx", "clip_fraction",
                 "collect_fps", "update_fps", "stage3_frac"):
        lines = open(f"{out}/scalars/{name}.csv").read().splitlines()
        assert len(lines) == 2 and lines[-1].startswith("1200,")
    report = open(result["report"]).read()
    assert "learning_curve.png" in report and "| unseen | **all** |" in report
    assert set(result["eval"]) == {"seen", "unseen"}
    assert result["eval"]["unseen"]["episodes"] == len(objects_lib.list_objects("laptop", "unseen"))


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="resident memory is read from Linux's /proc")
def test_heap_memory_freed_by_many_small_objects_goes_back_to_the_os_when_trimmed():
    # ~240 MB in 4 kB objects (malloc's, not pymalloc's), 9 in 10 freed: the holes are whole pages that glibc keeps
    # until malloc_trim, as it keeps a PPO update's freed activations (utils.release_freed_memory, trim_memory)
    release_freed_memory()  # what earlier tests freed goes back first, so the new objects take fresh pages
    base = resident_mb()
    chunks = [bytes(4000) for _ in range(60_000)]
    assert resident_mb() - base > 200
    kept = chunks[::10]
    del chunks
    before = resident_mb()
    release_freed_memory()
    assert before - resident_mb() > 150 and len(kept) == 6000


def test_checkpoint_reloads_and_evaluates_from_the_command_line(tiny_run, tmp_path, capsys):
    cfg, result = tiny_run
    payload = load_checkpoint(result["checkpoint"])
    assert payload["frames"] == 1200 and payload["config"]["num_points"] == 32
    out = tmp_path / "eval.json"
    code = cli.main(["eval", "--ckpt", result["checkpoint"], "--split", "unseen", "--episodes-per-object", "1",
                     "--seed", "7", "--json", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "| unseen | **all** |" in printed
    res = json.loads(out.read_text())
    names = [o.name for o in objects_lib.list_objects("laptop", "unseen")]
    assert list(res["objects"]) == names and res["episodes"] == len(names)
    assert 0.0 <= res["success_rate"] <= 1.0 and 1.0 <= res["mean_max_stage"] <= 3.0
    # same seed, same result: deterministic actions, seeded env
    prepared = []  # the prepare_env hook sees the unwrapped env once, before the first reset
    again = evaluate(actor_critic_from_checkpoint(payload), "laptop", "unseen", 1, 7,
                     {"num_points": 32, "max_episode_steps": 20},
                     prepare_env=lambda env: prepared.append((env is env.unwrapped, env.sensor.camera is not None)))
    assert again["objects"] == res["objects"] and prepared == [(True, True)]


def test_resume_continues_the_run(tiny_run, tmp_path):
    cfg, result = tiny_run
    run_dir = tmp_path / "copy"
    shutil.copytree(cfg.out, run_dir)
    with pytest.raises(ValueError, match="already holds a run; pass --resume"):
        ppo.train(dataclasses.replace(cfg, out=str(run_dir), frames=1500))
    resumed = ppo.train(dataclasses.replace(cfg, out=str(run_dir), frames=1600, frames_per_batch=400, workers=0,
                                            resume=True, eval_episodes=0))
    assert [h["frames"] for h in resumed["history"]] == [600, 1200, 1600]
    assert resumed["history"][:2] == result["history"]
    assert load_checkpoint(resumed["checkpoint"])["batches"] == 3


def test_pretrained_encoder_is_loaded_and_can_be_frozen(tmp_path):
    encoder = PointNetEncoder("small")
    torch.nn.init.normal_(encoder.mlp[2].weight)
    path = save_encoder(encoder, tmp_path / "enc.pt")
    cfg = tiny_config(tmp_path, frames=200, frames_per_batch=200, workers=0, eval_episodes=0,
                      pretrained=str(path), freeze_encoder=True)
    result = ppo.train(cfg)
    trained = actor_critic_from_checkpoint(load_checkpoint(result["checkpoint"]))
    for a, b in zip(encoder_of(trained).state_dict().values(), encoder.state_dict().values()):
        assert torch.equal(a, b)
    assert not torch.equal(trained.module[0].module.state_mlp[0].weight,
                           make_actor_critic(32, 22).module[0].module.state_mlp[0].weight)


def test_critic_learning_rate_and_target_kl_early_stop(tmp_path):
    """The value head gets its own learning rate; a tiny target KL stops the epochs after the first step."""
    from functools import partial

    cfg = tiny_config(tmp_path, frames=200, frames_per_batch=200, minibatch=50, epochs=3, workers=0,
                      eval_episodes=0, lr=1e-4, critic_lr=1e-3, target_kl=1e-9)
    learner = ppo.build_learner(cfg, partial(make_env, "laptop", num_points=32, max_episode_steps=20))
    policy_group, value_group = learner.optimizer.param_groups
    assert (policy_group["lr"], value_group["lr"]) == (1e-4, 1e-3)
    assert set(value_group["params"]) == set(learner.actor_critic.get_value_head().parameters())
    rows = ppo.train(cfg)["history"]
    assert 0 < rows[0]["update_steps_frac"] < 0.5  # 1 or a few of the 12 planned minibatch steps
    full = ppo.train(dataclasses.replace(cfg, target_kl=None, out=str(tmp_path / "full")))["history"]
    assert full[0]["update_steps_frac"] == 1.0


def test_detached_critic_trains_only_the_value_head(tmp_path):
    """With critic_detach the value loss moves the value head and nothing of the shared trunk; without it,
    the trunk gets a gradient from the value loss too (DexArt's shared actor-critic)."""
    from functools import partial

    for detach in (True, False):
        cfg = tiny_config(tmp_path, frames=200, frames_per_batch=200, workers=0, eval_episodes=0, critic_detach=detach)
        learner = ppo.build_learner(cfg, partial(make_env, "laptop", num_points=32, max_episode_steps=20))
        env = make_env("laptop", num_points=32, max_episode_steps=20, seed=0)
        with torch.no_grad():
            data = env.rollout(20, learner.actor_critic)  # the whole actor-critic, as the collectors run it
        env.close()
        flat = ppo.advantages(data, learner)
        learner.optimizer.zero_grad()
        learner.loss_module(flat)["loss_critic"].backward()
        trunk = learner.actor_critic.module[0].module
        value = list(learner.actor_critic.get_value_head().parameters())
        assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in value)
        trunk_grad = sum(float(p.grad.abs().sum()) for p in trunk.parameters() if p.grad is not None)
        assert (trunk_grad == 0.0) if detach else (trunk_grad > 0.0)


def test_reward_scale_scales_the_rewards_gae_sees(tmp_path):
    """GAE's advantage is affine in the rewards: A(c) - A(1) = (c - 1) * sum_k (gamma lambda)^k r_{t+k}, so
    A(3) - A(1) = 2 (A(2) - A(1)); the episode returns that are logged stay unscaled."""
    from functools import partial

    cfg = tiny_config(tmp_path, frames=200, frames_per_batch=200, workers=0, eval_episodes=0)
    learner = ppo.build_learner(cfg, partial(make_env, "laptop", num_points=32, max_episode_steps=20))
    env = make_env("laptop", num_points=32, max_episode_steps=20, seed=0)
    with torch.no_grad():
        data = env.rollout(20, learner.actor_critic)
    env.close()
    returns = data["next", "episode_reward"].clone()
    adv = {c: ppo.advantages(data.clone(), learner, c)["advantage"] for c in (1.0, 2.0, 3.0)}
    assert not torch.allclose(adv[1.0], adv[2.0])
    torch.testing.assert_close(adv[3.0] - adv[1.0], 2 * (adv[2.0] - adv[1.0]), rtol=1e-4, atol=1e-5)
    assert torch.equal(data["next", "episode_reward"], returns)
    with pytest.raises(ValueError, match="reward_scale must be"):
        ppo.validate(tiny_config(tmp_path, reward_scale=0.0))


def test_distributed_backend_on_loopback(tmp_path):
    cfg = tiny_config(tmp_path, frames=400, frames_per_batch=200, workers=2, backend="distributed",
                      eval_episodes=0, tcp_port=free_port())
    result = ppo.train(cfg)
    assert [h["frames"] for h in result["history"]] == [200, 400]
    assert all(math.isfinite(h["loss_critic"]) for h in result["history"])


# ------------------------------------------------------------------ one-line errors
def test_missing_or_corrupt_checkpoints_give_one_line_errors(tmp_path, capsys):
    assert cli.main(["eval", "--ckpt", str(tmp_path / "none.pt")]) == 2
    err = capsys.readouterr().err.strip()
    assert "checkpoint not found" in err and len(err.splitlines()) == 1
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"PK\x03\x04 not really a zip" * 20)
    assert cli.main(["eval", "--ckpt", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "not a readable checkpoint" in err and len(err.splitlines()) == 1
    torch.save({"something": 1}, tmp_path / "other.pt")
    assert cli.main(["eval", "--ckpt", str(tmp_path / "other.pt")]) == 2
    assert "not a dexart_lite PPO checkpoint" in capsys.readouterr().err
    with pytest.raises(FileNotFoundError, match="pretrained encoder not found"):
        ppo.train(tiny_config(tmp_path, pretrained=str(tmp_path / "none.pt")))


# ------------------------------------------------------------------ the demo (`make demo`)
def test_demo_distils_evaluates_and_writes_report_curve_gif_and_checkpoint(tmp_path, capsys):
    from PIL import Image

    assert cli.main(["demo", "--out", str(tmp_path)]) == 0  # fast mode: a few dozen frames
    (run_dir,) = tmp_path.iterdir()  # one fresh dated folder per demo
    printed = capsys.readouterr().out
    for name in ("report.md", "rounds.png", "episode.gif", "checkpoint.pt"):
        assert (run_dir / name).is_file(), name
        assert str(run_dir / name) in printed
    assert "seen   success" in printed and "unseen success" in printed
    for split in ("seen", "unseen"):
        assert 0.0 <= json.loads((run_dir / f"eval_{split}.json").read_text())["success_rate"] <= 1.0
    with Image.open(run_dir / "episode.gif") as gif:
        assert gif.n_frames > 1
    payload = load_checkpoint(run_dir / "checkpoint.pt")
    assert payload["trainer"] == "distill" and payload["frames"] > 0


def test_demo_rejects_a_non_positive_budget(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path), "--minutes", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--minutes must be > 0" in err and len(err.splitlines()) == 1
    assert not any(tmp_path.iterdir())


def test_state_only_diagnostic_never_renders_and_trains_an_mlp(tmp_path, monkeypatch):
    """--obs state: the state vector (32 on Laptop) plus the 15 documented privileged entries, no camera
    call at any reset or step, and PPO trains and evaluates an MLP actor-critic on it."""
    from dexart_lite.camera import DepthCamera
    from dexart_lite.envs import make
    from dexart_lite.envs.base import PRIVILEGED_STATE

    def no_camera(*args, **kwargs):
        raise AssertionError("the state-only observation rendered the camera")

    monkeypatch.setattr(DepthCamera, "render_depth", no_camera)
    env = make("laptop", observation="state", num_points=32, max_episode_steps=5)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"state"} and obs["state"].shape == (32 + PRIVILEGED_STATE,) == (47,)
    s = env.unwrapped._state
    extra = obs["state"][32:]
    np.testing.assert_allclose(extra[9:12], [s.q, s.obj.joint_init, s.obj.joint_target], atol=1e-6)
    np.testing.assert_allclose(extra[12:], s.handle_pos - np.asarray(env.unwrapped.ROBOT_BASE), atol=1e-6)
    for _ in range(5):
        obs, *_ = env.step(env.action_space.sample())
    env.close()
    # a wider network than DexArt's (--head, --state-hidden): recorded in the checkpoint, rebuilt from it strictly
    cfg = tiny_config(tmp_path, obs="state", frames=200, frames_per_batch=100, minibatch=50, workers=0,
                      eval_episodes=1, head="48,40", state_hidden=24)
    result = ppo.train(cfg)
    assert result["frames"] == 200 and 0.0 <= result["eval"]["seen"]["success_rate"] <= 1.0
    payload = load_checkpoint(result["checkpoint"])
    assert payload["dims"]["head"] == [48, 40] and payload["dims"]["state_hidden"] == 24
    net = actor_critic_from_checkpoint(payload, result["checkpoint"])
    assert net.module[0].module.encoder is None and net.module[0].in_keys == ["observation"]
    assert net.module[0].module.state_mlp[0].out_features == 24
    assert [m.out_features for m in net.module[1].module[0].module[0] if isinstance(m, torch.nn.Linear)] == [48, 40, 22]
    with pytest.raises(ValueError, match="another shape"):  # resumed with another network: one line, not a traceback
        ppo.train(dataclasses.replace(cfg, head="64,64", frames=300, resume=True))
    with pytest.raises(ValueError, match="valid choices: cloud, state"):
        ppo.validate(tiny_config(tmp_path, obs="image"))
    with pytest.raises(ValueError, match="comma-separated positive widths"):
        ppo.validate(tiny_config(tmp_path, head="64,0"))
    with pytest.raises(ValueError, match="brings its own architecture"):
        initial_weights(tiny_config(tmp_path, head="128,128", init_from=result["checkpoint"]), 47, 22)


def test_observation_normalisation_is_fixed_from_a_rollout_of_the_initial_policy(tmp_path):
    """--obs-norm-steps N: the trunk's centre and scale are the mean and std of the N states (and points) the
    initial policy visits in an env seeded with the run's seed; they travel in the checkpoint, and a network
    from --init-from keeps its own."""
    cfg = tiny_config(tmp_path, obs_norm_steps=30, seed=3)
    env_fn = partial(make_env, cfg.task, **cfg.env_kwargs())
    torch.manual_seed(0)
    learner = ppo.build_learner(cfg, env_fn)
    trunk = trunk_of(learner.actor_critic)
    # the same rollout again: same initial weights, same torch RNG stream, same env seed
    torch.manual_seed(0)
    fresh = make_actor_critic(*env_dims(env_fn())[1:], "small", cfg.init_log_std, normalize=True)
    env = env_fn(seed=3)
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        td = env.rollout(30, fresh.get_policy_operator(), break_when_any_done=False)
    env.close()
    states, points = td["observation"], td["point_cloud"].reshape(-1, 3)
    assert states.shape[0] == 30
    torch.testing.assert_close(trunk.state_loc, states.mean(0))
    torch.testing.assert_close(trunk.state_scale, states.std(0).clamp_min(1e-2))
    torch.testing.assert_close(trunk.point_loc, points.mean(0))
    assert learner.dims["normalize"] is True and not torch.equal(trunk.state_loc, torch.zeros_like(trunk.state_loc))
    assert any(k.endswith("state_loc") for k in learner.actor_critic.state_dict())  # saved with the weights
    with pytest.raises(ValueError, match="--init-from brings its own input normalisation"):
        ppo.validate(tiny_config(tmp_path, obs_norm_steps=30, init_from=__file__))
    assert ppo.PRESETS["fast"]["obs_norm_steps"] > 0 and ppo.PPOConfig().obs_norm_steps == 0  # DexArt: raw inputs


def test_self_imitation_buffer_keeps_the_best_finished_episodes_with_their_discounted_returns():
    """rl/sil.py: returns to the end of each episode computed by hand; the steps after a worker's last episode
    end (their episode goes on in the next batch) are never stored; the best episodes fill the capacity."""
    from dexart_lite.rl.sil import RETURN_KEY, SelfImitationBuffer, episode_returns

    returns = episode_returns(torch.tensor([1.0, 0.0, 2.0, 1.0, 1.0]),
                              torch.tensor([False, True, False, False, False]), gamma=0.5)
    torch.testing.assert_close(returns, torch.tensor([1.0 + 0.5 * 0.0, 0.0, 2.0 + 0.5 * 1.5, 1.0 + 0.5, 1.0]))

    # 2 workers x 6 steps; worker 0: episodes [0-2] (return 3) and [3-4] (10), then an unfinished step;
    # worker 1: episode [0-2] (return 10), then 3 unfinished steps
    reward = torch.tensor([[1.0, 1, 1, 5, 5, 7], [0, 0, 10, 0, 0, 7]])
    done = torch.tensor([[0, 0, 1, 0, 1, 0], [0, 0, 1, 0, 0, 0]]).bool()
    data = TensorDict({"observation": torch.arange(12.0).reshape(2, 6, 1), "action": torch.zeros(2, 6, 22),
                       "next": {"reward": reward[..., None], "done": done[..., None]}}, [2, 6])
    buffer = SelfImitationBuffer(capacity=5, gamma=1.0)
    assert buffer.add(data) == 3
    assert len(buffer) == 5 and [score for score, _ in buffer.episodes] == [10.0, 10.0]  # the return-3 one is out
    stored = sorted(buffer.steps["observation"].reshape(-1).tolist())
    assert stored == [3.0, 4.0, 6.0, 7.0, 8.0]  # never step 5 or 9-11 (unfinished episodes)
    by_obs = dict(zip(buffer.steps["observation"].reshape(-1).tolist(), buffer.steps[RETURN_KEY].tolist()))
    assert by_obs == {3.0: 10.0, 4.0: 5.0, 6.0: 10.0, 7.0: 10.0, 8.0: 10.0}
    sample = buffer.sample(7, torch.Generator().manual_seed(0))
    assert sample.batch_size == torch.Size([7]) and set(sample["observation"].reshape(-1).tolist()) <= set(stored)
    with pytest.raises(ValueError, match="capacity must be >= 1 step"):
        SelfImitationBuffer(capacity=0, gamma=0.99)


def test_self_imitation_loss_pulls_only_towards_actions_that_beat_the_critic():
    """L_sil = -log pi(a|s) (R - V)+ + c 0.5 ((R - V)+)^2: zero (and no gradient) where the critic already
    expects the stored return; where the return is higher, one gradient step makes the stored action more
    likely and raises V towards R."""
    from dexart_lite.rl.sil import RETURN_KEY, sil_loss

    torch.manual_seed(0)
    net = make_actor_critic(5, 22, "none", init_log_std=-1.0)  # the state MLP trunk
    policy, critic = net.get_policy_operator(), net.get_value_head()
    samples = TensorDict({"observation": torch.randn(8, 5), "action": torch.rand(8, 22) * 2 - 1}, [8])
    with torch.no_grad():
        td = samples.exclude("action").clone()
        log_prob_before = policy.get_dist(td).log_prob(samples["action"])
        value = critic(td)["state_value"].reshape(-1)
    samples[RETURN_KEY] = value - 1.0  # worse than expected: nothing to imitate
    loss, parts = sil_loss(policy, critic, samples, value_coef=0.01)
    loss.backward()
    assert float(loss.detach()) == 0.0 and parts["sil_positive"] == 0.0
    assert all(p.grad is None or not p.grad.any() for p in net.parameters())
    samples[RETURN_KEY] = value + 1.0  # better than expected
    optimizer = torch.optim.SGD(net.parameters(), lr=1e-3)
    loss, parts = sil_loss(policy, critic, samples, value_coef=0.01)
    optimizer.zero_grad()
    loss.backward()
    optimizer.step()
    assert parts["sil_positive"] == 1.0 and parts["loss_sil_value"] == pytest.approx(0.5, rel=1e-4)
    with torch.no_grad():
        td = samples.exclude("action", RETURN_KEY).clone()
        assert policy.get_dist(td).log_prob(samples["action"]).mean() > log_prob_before.mean()
        assert (critic(td)["state_value"].reshape(-1) > value).float().mean() > 0.5


def test_tiny_run_with_self_imitation_logs_its_loss_and_buffer(tmp_path):
    cfg = tiny_config(tmp_path, obs="state", frames=200, frames_per_batch=100, minibatch=50, workers=0,
                      eval_episodes=0, sil_coef=1.0, sil_capacity=60)
    history = ppo.train(cfg)["history"]
    assert [row["sil_steps"] for row in history] == [60, 60]  # 20-step episodes: 5 per batch, the best 3 kept
    assert all(math.isfinite(row["loss_sil"]) and 0.0 <= row["sil_positive"] <= 1.0 for row in history)
    assert ppo.PPOConfig().sil_coef == 0.0  # DexArt: no replay


def test_tiny_run_with_the_synergy_hand_trains_and_evaluates_a_9d_policy(tmp_path):
    """hand="synergy": the policy has 9 action dims, and its checkpoint rebuilds the synergy env to evaluate."""
    from dexart_lite.rl.checkpoint import observation_kwargs

    cfg = tiny_config(tmp_path, obs="state", hand="synergy", frames=200, frames_per_batch=100, minibatch=50,
                      workers=0, eval_episodes=1)
    result = ppo.train(cfg)
    payload = load_checkpoint(result["checkpoint"])
    assert payload["dims"]["action_dim"] == 9 and observation_kwargs(payload)["hand"] == "synergy"
    assert cli.main(["eval", "--ckpt", result["checkpoint"], "--split", "unseen", "--episodes-per-object", "1"]) == 0
    with pytest.raises(ValueError, match="valid choices: joints, synergy"):
        ppo.validate(tiny_config(tmp_path, hand="gripper"))
    assert ppo.PPOConfig().hand == "joints"  # DexArt: 16 hand joint targets


def test_bench_learning_set_changes_ppo_fields_and_records_them(tmp_path, monkeypatch, load_benchmark):
    """benchmarks/rl/bench_learning.py --set: typed PPOConfig fields, recorded as departures in the JSON;
    it needs --tag, and fields the script sets itself are refused."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_learning")
    out = tmp_path / "run"
    with pytest.raises(ValueError, match="needs a --tag"):
        bench.main(["--set", "obs=state", "--out", str(out)])
    with pytest.raises(ValueError, match="--set frames: use the script's own option"):
        bench.main(["--set", "frames=10", "--tag", "x", "--out", str(out)])
    summary = bench.main(["--preset", "cpu", "--workers", "0", "--tag", "state", "--out", str(out),
                          "--set", "obs=state", "reward=shaped", "reward_scale=0.01"])
    assert summary["departures_from_preset"] == {"obs": "state", "reward": "shaped", "reward_scale": 0.01}
    assert summary["config"]["obs"] == "state" and summary["config"]["reward_scale"] == 0.01
    assert (out / "results" / "learning_laptop_state.json").is_file()  # fast mode never writes the committed results


def test_state_diagnostic_reports_frames_to_first_success_and_reads_back_only_identical_runs(
        tmp_path, monkeypatch, load_benchmark):
    """benchmarks/rl/state_diagnostic.py: one fast run per task and seed through bench_learning; frames to first
    success is the first batch with a collected success; an earlier JSON is reused only with the same settings."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("state_diagnostic")
    points = [{"frames": 4000, "success_rate": 0.0, "stage3_frac": 0.0},
              {"frames": 8000, "success_rate": 0.0, "stage3_frac": 0.01},
              {"frames": 12000, "success_rate": 0.25, "stage3_frac": 0.2}]
    assert bench.first_frames(points, "success_rate") == 12000 and bench.first_frames(points, "stage3_frac") == 8000
    assert bench.first_frames(points[:2], "success_rate") is None
    result = bench.main(["--tasks", "faucet", "--seeds", "0", "--json", str(tmp_path / "diag.json")])
    run = result["tasks"]["faucet"]["per_seed"][0]
    assert run["frames"] == 800 and run["read_back"] is False and result["fast_mode"] is True
    assert (tmp_path / "diag.png").is_file()
    path = tmp_path / "learning_faucet_state_dexart_s0.json"
    written = json.loads(path.read_text())
    assert written["config"]["obs"] == "state" and written["config"]["init_log_std"] == bench.INIT_LOG_STD
    assert bench.finished(path, frames=800, eval_episodes=1) == written  # identical settings: reused
    assert bench.finished(path, frames=300_000, eval_episodes=1) is None  # other budget: run again
    written["departures_from_preset"]["reward"] = "shaped"
    path.write_text(json.dumps(written))
    assert bench.finished(path, frames=800, eval_episodes=1) is None
    # --preset fast: the fast PPO preset (the same departures plus the input normalisation), its own run names
    bench.main(["--preset", "fast", "--tasks", "faucet", "--seeds", "0", "--json", str(tmp_path / "fast.json")])
    path = tmp_path / "learning_faucet_state_fast_s0.json"
    written = json.loads(path.read_text())
    assert written["preset"] == "fast" and written["departures_from_preset"] == {"obs": "state"}
    assert written["config"]["obs_norm_steps"] == 2000 and written["config"]["init_log_std"] == bench.INIT_LOG_STD
    assert written["config"]["lr"] == 3e-4 and written["config"]["reward_scale"] == 0.01
    assert bench.finished(path, frames=800, eval_episodes=1, preset="fast") == written
    assert bench.finished(path, frames=800, eval_episodes=1, preset="cpu") is None
    # --preset fast_sil: the fast PPO preset plus self-imitation, one more departure
    assert bench.run_args("faucet", 0, 800, 1, tmp_path, tmp_path, "fast_sil")[:6] == [
        "--task", "faucet", "--preset", "fast", "--seed", "0"]
    assert bench.finished(path, frames=800, eval_episodes=1, preset="fast_sil") is None
    # --preset fast_synergy: the fast PPO preset with the 9-D synergy hand
    assert bench.run_args("faucet", 0, 800, 1, tmp_path, tmp_path, "fast_synergy")[10:13] == [
        "--set", "obs=state", "hand=synergy"]


def test_the_training_benchmark_compares_a_whole_iteration_with_an_earlier_commit(load_benchmark, git_checkout):
    """Structure only (timings are the benchmark's business): two 100-frame cpu-preset batches collected
    in-process, this checkout against a worktree of HEAD, each in its own interpreter."""
    bench = load_benchmark("bench_training")
    row = bench.iteration_vs_ref("HEAD", "laptop", batches=2, rounds=1, frames_per_batch=100, workers=0)
    assert row["iteration_fps_subprocess"] > 0 and row["ref_iteration_fps"] > 0
    assert row["iteration_vs_ref"] == pytest.approx(row["iteration_fps_subprocess"] / row["ref_iteration_fps"])
    assert row["ref"] == "HEAD" and row["ref_frames_per_batch"] == 100
    calls = bench.policy_call_ms(calls=2, rounds=1)  # the one-action timing of both policy forms
    assert set(calls) == {"actor_critic", "acting", "acting_speedup"} and calls["acting"] > 0
    assert calls["acting_speedup"] == pytest.approx(calls["actor_critic"] / calls["acting"])


def test_the_training_benchmarks_physics_option_reaches_the_envs_and_nothing_else(load_benchmark):
    """--physics 20x5: the cpu preset's learning settings unchanged, every env built from the config with 20
    solver iterations and 5 sub-steps of 8 ms (the control step stays 40 ms); a bad setting is refused
    before anything is measured."""
    from dexart_lite.envs.base import physics_setting

    bench = load_benchmark("bench_training")
    cfg = ppo.preset("cpu", task="laptop")
    fast = bench.PhysicsPPOConfig(physics_setting("20x5"), **dataclasses.asdict(cfg))
    assert dataclasses.asdict(fast) == dataclasses.asdict(cfg)
    assert fast.env_kwargs() == {**cfg.env_kwargs(), "solver_iterations": 20, "frame_skip": 5, "dt": 0.008}
    env = make_env("laptop", **fast.env_kwargs())
    try:
        inner = env.base_env._env.unwrapped
        assert inner.frame_skip == 5 and inner.control_dt == pytest.approx(0.04)
    finally:
        env.close()
    with pytest.raises(ValueError, match="ITERATIONSxFRAME_SKIP"):
        bench.main(["--physics", "20", "--only-physics"])


def test_the_memory_benchmark_trains_both_arms_and_reads_memory_per_batch(load_benchmark, monkeypatch, tmp_path):
    """Fast mode: two 2-batch runs, one trimming, one after the other in this process (the script's figures run
    them side by side); rss_mb of every batch of each, the JSON written."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_train_memory")
    result = bench.main(["--task", "laptop", "--jobs", "1", "--json", str(tmp_path / "m.json")])
    for arm in ("trim", "no_trim"):
        assert len(result[arm]["rss_mb"]) == 2 and all(v > 50 for v in result[arm]["rss_mb"])
    assert result["fps_ratio"] > 0 and json.loads((tmp_path / "m.json").read_text())["batches"] == 2


def test_train_help_lists_every_preset_and_option_with_its_faithful_value(capsys):
    """`dexart-lite train --help`: every preset, and every PPOConfig field as a flag whose help ends with its
    DexArt (faithful preset) value, e.g. the fine-tuning guards that DexArt does not have."""
    import argparse

    with pytest.raises(SystemExit) as exit_info:
        cli.main(["train", "--help"])
    assert exit_info.value.code == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert f"starting point: {', '.join(ppo.PRESETS)}" in text
    parser = argparse.ArgumentParser()
    ppo.add_arguments(parser)
    helps = {a.dest: a.help for a in parser._actions}
    for f in dataclasses.fields(ppo.PPOConfig):
        assert "--" + f.name.replace("_", "-") in text, f.name
        assert helps[f.name].endswith(f"(faithful preset: {f.default})"), f.name
    assert "KL penalty to the --init-from policy" in helps["anchor_coef"] and ppo.PPOConfig().anchor_coef == 0.0
