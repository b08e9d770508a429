"""Contracts of ``--device cpu|cuda|auto`` (utils.resolve_device; train, distill, pretrain, eval): cuda where
there is none is a one-line error and never a silent fallback, auto falls back and says so, and what is saved
is on the CPU. These run on CPU machines: CUDA is switched off here so that they hold on a GPU machine too."""

from __future__ import annotations

import dataclasses
import json
import sys
from functools import partial
from pathlib import Path

import pytest
import torch

from dexart_lite import cli
from dexart_lite.imitation.distill import DistillConfig, distill
from dexart_lite.imitation.distill import validate as validate_distill
from dexart_lite.pretrain.train import PretrainConfig
from dexart_lite.pretrain.train import validate as validate_pretrain
from dexart_lite.rl import ppo, sac
from dexart_lite.rl.checkpoint import load_checkpoint
from dexart_lite.rl.env import make_env
from dexart_lite.utils import resolve_device


@pytest.fixture
def no_cuda(monkeypatch):
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)


def test_cuda_without_cuda_is_an_error_and_auto_says_what_it_chose(no_cuda, monkeypatch):
    with pytest.raises(ValueError, match="--device cuda: this machine has no CUDA device"):
        resolve_device("cuda")
    lines = []
    assert resolve_device("auto", log=lines.append) == torch.device("cpu")
    assert lines == ["--device auto: using cpu (no CUDA device)"]
    assert resolve_device("cpu") == torch.device("cpu")
    with pytest.raises(ValueError, match="unknown device 'gpu'; valid choices: cpu, cuda, auto"):
        resolve_device("gpu")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)  # where there is one, auto takes it
    assert resolve_device("auto", log=lines.append) == torch.device("cuda") and lines[-1] == "--device auto: using cuda"


def test_every_command_refuses_cuda_where_there_is_none_before_any_work(no_cuda, capsys):
    for config in (dataclasses.replace(ppo.PPOConfig(), device="cuda"), sac.SACConfig(device="cuda"),
                   DistillConfig(device="cuda"), PretrainConfig(device="cuda")):
        validate = {ppo.PPOConfig: ppo.validate, sac.SACConfig: sac.validate, DistillConfig: validate_distill,
                    PretrainConfig: validate_pretrain}[type(config)]
        with pytest.raises(ValueError, match="no CUDA device"):
            validate(config)
    for argv in (["train", "--task", "laptop", "--device", "cuda"], ["train", "--algo", "sac", "--device", "cuda"],
                 ["distill", "--device", "cuda"],
                 ["pretrain", "--device", "cuda"], ["eval", "--ckpt", "zoo:laptop", "--device", "cuda"]):
        assert cli.main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert "no CUDA device" in err and "\n" not in err and "Traceback" not in err, err


def test_auto_trains_on_the_cpu_where_there_is_no_cuda_and_saves_cpu_tensors(no_cuda, tmp_path, capsys):
    cfg = dataclasses.replace(ppo.PPOConfig(), task="laptop", num_points=32, max_episode_steps=20, frames=200,
                              frames_per_batch=200, minibatch=100, epochs=1, workers=0, eval_episodes=0,
                              progress=False, device="auto", out=str(tmp_path / "run"))
    result = ppo.train(cfg)
    assert result["device"] == "cpu" and "--device auto: using cpu (no CUDA device)" in capsys.readouterr().out
    payload = load_checkpoint(result["checkpoint"])
    assert payload["config"]["device"] == "auto"
    tensors = [*payload["model"].values(), *(v for s in payload["optimizer"]["state"].values() for v in s.values())]
    assert tensors and all(t.device.type == "cpu" for t in tensors if isinstance(t, torch.Tensor))


def test_on_the_cpu_the_learner_acts_with_its_own_network():
    """Learner.to(cpu) keeps one network: the collectors act with the weights the loss updates (no copy to sync)."""
    cfg = dataclasses.replace(ppo.PPOConfig(), task="laptop", num_points=32, obs="state")
    learner = ppo.build_learner(cfg, partial(make_env, "laptop", observation="state"))
    acting = learner.to(torch.device("cpu"))
    assert acting is learner.actor_critic and learner.device == torch.device("cpu")
    learner.sync_acting(acting)  # nothing to do, and nothing changes
    assert acting is learner.actor_critic


def test_distill_on_auto_trains_on_the_cpu_and_says_so(no_cuda, tmp_path):
    cfg = DistillConfig(task="laptop", objects="laptop_11cbb00f39", demo_episodes_per_object=1, rounds=1,
                        episodes_per_round=1, epochs=1, epochs_per_round=1, batch_size=16, num_points=32,
                        max_episode_steps=8, eval_episodes=0, threads=1, progress=False, device="auto",
                        out=str(tmp_path / "run"))
    result = distill(cfg)
    assert result["device"] == "cpu"
    assert all(t.device.type == "cpu" for t in load_checkpoint(result["checkpoint"])["model"].values())


def test_device_check_writes_the_fields_it_documents(tmp_path, load_benchmark):
    bench = load_benchmark("device_check")
    result = bench.main(["--devices", "cpu", "--frames", "400", "--workers", "1", "--epochs", "1",
                         "--json", str(tmp_path / "check.json")])  # fast mode (conftest): the CPU half, small
    cpu = result["per_device"]["cpu"]
    assert cpu["ppo"]["frames"] == 400 and cpu["ppo"]["update_fps"] > 0 and cpu["distill"]["samples"] > 0
    assert result["ratios_vs_first"]["cpu"]["ppo_update_fps"] == 1.0 and "gpu" in result["machine"]


def test_bench_scaling_writes_the_fields_it_documents(tmp_path, load_benchmark):
    path = tmp_path / "scaling.json"
    bench = load_benchmark("bench_scaling")
    result = bench.main(["--backends", "process", "--workers", "1", "2", "--frames", "40", "--per-worker", "20",
                         "--steps", "20", "--json", str(path)])  # fast mode (conftest): 20-step episodes, 64 points
    assert json.loads(path.read_text()) == json.loads(json.dumps(result))
    assert set(result["collection"]["process"]) == {"1", "2"} and all(v > 0 for v in result["collection"]["process"].values())
    assert set(result["plain_env"]) == {"1", "2"} and result["plain_env"]["2"]["total"] > 0
    assert result["ray"] in ("not asked for", "not installed (pip install '.[distributed]')") and result["fast_mode"]
    assert (tmp_path / "scaling.png").stat().st_size > 0


def test_an_optimizer_state_follows_its_parameters_but_adam_s_step_stays():
    from dexart_lite.utils import optimizer_to

    net = torch.nn.Linear(3, 2)
    optimizer = torch.optim.Adam(net.parameters())
    net(torch.ones(1, 3)).sum().backward()
    optimizer.step()
    moved = []
    for state in optimizer.state.values():  # a stand-in device: record what is asked to move, by key
        for key in list(state):
            state[key] = _Recorder(state[key], key, moved) if key != "step" else state[key]
    optimizer_to(optimizer, torch.device("cpu"))
    assert sorted(moved) == ["exp_avg", "exp_avg", "exp_avg_sq", "exp_avg_sq"]


class _Recorder(torch.Tensor):
    """A tensor that notes each ``.to`` call (optimizer_to moves Adam's moments, never its step counter)."""

    @staticmethod
    def __new__(cls, tensor, key, log):
        out = tensor.as_subclass(cls)
        out.key, out.log = key, log
        return out

    def to(self, *args, **kwargs):
        self.log.append(self.key)
        return super().to(*args, **kwargs)
