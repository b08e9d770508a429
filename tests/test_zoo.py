"""Contracts of the shipped policies (dexart_lite/zoo, benchmarks/students/zoo_build.py): each loads strictly and acts on
its task, its manifest numbers are those of the JSON they were measured in, and a bad name is one line."""

from __future__ import annotations

import dataclasses
import json
from functools import partial
from pathlib import Path

import numpy as np
import pytest

from dexart_lite import cli, zoo
from dexart_lite.envs import make
from dexart_lite.rl import ppo
from dexart_lite.rl.checkpoint import checkpoint_path, load_checkpoint, load_policy, observation_kwargs
from dexart_lite.rl.env import make_env

ROOT = Path(__file__).resolve().parent.parent
EVIDENCE = ROOT / "benchmarks" / "results" / "students" / "zoo.json"


def test_every_shipped_policy_loads_strictly_and_acts_on_its_task():
    entries = zoo.manifest()
    if not entries:
        pytest.skip("no policy shipped in dexart_lite/zoo yet")
    for task, entry in entries.items():
        path = checkpoint_path(f"zoo:{task}")
        payload = load_checkpoint(path)
        assert path.stat().st_size <= zoo.MAX_BYTES and payload["config"]["task"] == task
        env = make(task, max_episode_steps=5, **observation_kwargs(payload))
        act = load_policy(f"zoo:{task}", env)  # strict load of every weight, the normalisation included
        obs, _ = env.reset(seed=0)
        for _ in range(3):
            action = act(obs)
            assert action.shape == (22,) and np.isfinite(action).all()
            obs, *_ = env.step(action)
        env.close()


def test_the_manifest_holds_the_numbers_of_the_json_they_were_measured_in():
    if not zoo.manifest():
        pytest.skip("no policy shipped in dexart_lite/zoo yet")
    measured = json.loads(EVIDENCE.read_text())
    assert zoo.manifest() == measured["policies"] and not measured["fast_mode"]
    for task, entry in measured["policies"].items():
        assert entry["file"] == f"{task}.pt" and 0.0 <= entry["seen_success"] <= 1.0
        assert entry["eval_episodes_per_object"] >= 3 and entry["training_command"]


def test_an_unknown_or_missing_zoo_policy_is_one_line_naming_the_valid_entries(tmp_path, monkeypatch, capsys):
    valid = ", ".join(f"zoo:{k}" for k in sorted(zoo.manifest()))
    with pytest.raises(ValueError, match=f"unknown zoo policy 'zoo:chair'; valid choices: {valid}"):
        load_checkpoint("zoo:chair")
    assert cli.main(["eval", "--ckpt", "zoo:chair"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("dexart-lite eval: error: unknown zoo policy") and "\n" not in err
    # a listed entry whose file is missing or corrupt, in a zoo folder of our own
    (tmp_path / "manifest.json").write_text(json.dumps({"policies": {"laptop": {"file": "laptop.pt"}}}))
    monkeypatch.setattr(zoo, "FOLDER", tmp_path)
    monkeypatch.setattr(zoo, "MANIFEST", tmp_path / "manifest.json")
    with pytest.raises(FileNotFoundError, match="its file laptop.pt is missing.*valid choices: zoo:laptop"):
        load_checkpoint("zoo:laptop")
    (tmp_path / "laptop.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="laptop.pt is not a readable checkpoint"):
        load_checkpoint("zoo:laptop")


def test_zoo_build_ships_a_checkpoint_without_its_optimizer_and_writes_the_fields_it_documents(tmp_path, load_benchmark):
    cfg = dataclasses.replace(ppo.PPOConfig(), task="laptop", num_points=32, max_episode_steps=5,
                              out=str(tmp_path / "run"))
    learner = ppo.build_learner(cfg, partial(make_env, "laptop", num_points=32, max_episode_steps=5))
    source = ppo.save(learner, cfg, tmp_path / "run.pt", frames=123, batches=0, history=[])
    assert "optimizer" in load_checkpoint(source)
    bench = load_benchmark("zoo_build")
    result = bench.main(["--policy", f"laptop={source}", "--eval-episodes", "1", "--zoo", str(tmp_path / "zoo"),
                         "--json", str(tmp_path / "zoo.json")])  # fast mode (conftest)
    entry = result["policies"]["laptop"]
    shipped = load_checkpoint(tmp_path / "zoo" / "laptop.pt")
    assert "optimizer" not in shipped and shipped["frames"] == entry["frames"] == 123
    assert json.loads((tmp_path / "zoo" / "manifest.json").read_text())["policies"] == result["policies"]
    for key in ("bytes", "trainer", "seed", "training_command", "seen_success", "unseen_success",
                "eval_episodes_per_object", "eval_seed", "mean_max_stage"):
        assert key in entry, key
    # a source that only collected finished runs (bench_distill --collect) is given the command that trained it
    (tmp_path / "source.json").write_text(json.dumps({"command": "bench_distill.py --collect runs/a", "machine": {}}))
    entry = bench.main(["--policy", f"laptop={source}", "--source", f"laptop={tmp_path / 'source.json'}",
                        "--training-command", "laptop=bench_distill.py --task laptop --set threads=1",
                        "--eval-episodes", "1", "--zoo", str(tmp_path / "zoo"), "--json", str(tmp_path / "zoo.json")])["policies"]["laptop"]
    assert entry["training_command"] == "bench_distill.py --task laptop --set threads=1"
    with pytest.raises(ValueError, match="not laptop|is a laptop policy, not faucet"):
        bench.main(["--policy", f"faucet={source}", "--zoo", str(tmp_path / "zoo"), "--json", str(tmp_path / "z.json")])
