"""No unseen object enters training or a choice: the learners refuse the unseen split, and every policy the
repository ships or continues (the zoo, the runs parked in benchmarks/results/in_progress) records a training split
of seen objects and training objects among them. (Pretraining datasets: tests/test_pretrain.py; choices made on
seen objects at validation seeds: tests/test_protocol.py.)"""

import json
from pathlib import Path

import pytest
import torch

from dexart_lite.imitation.distill import DistillConfig, validate
from dexart_lite.objects import TRAINING_SPLITS, list_objects
from dexart_lite.rl import ppo
from dexart_lite.zoo import FOLDER as ZOO, manifest

ROOT = Path(__file__).resolve().parent.parent
IN_PROGRESS = ROOT / "benchmarks" / "results" / "in_progress"


def trains_on_seen_objects_only(config: dict, where: str) -> None:
    assert config.get("split", "seen") in TRAINING_SPLITS, f"{where} trained on the {config['split']} split"
    training = {o.name for o in list_objects(config["task"], "seen_wide")}  # seen + the extra training toilets
    named = [n.strip() for n in (config.get("objects") or "").split(",") if n.strip()]
    assert set(named) <= training, f"{where} trained on unseen objects {sorted(set(named) - training)}"


def test_the_training_splits_hold_no_unseen_object():
    for task in ("faucet", "bucket", "laptop", "toilet"):
        unseen = {o.name for o in list_objects(task, "unseen")}
        seen_templates = {o.template for o in list_objects(task, "seen")}  # the held-out template is none of them
        for split in TRAINING_SPLITS:
            assert not unseen & {o.name for o in list_objects(task, split)}, (task, split)
            assert {o.template for o in list_objects(task, split)} <= seen_templates, (task, split)


def test_the_learners_refuse_to_train_on_unseen_objects():
    with pytest.raises(ValueError, match="training split"):
        validate(DistillConfig(task="laptop", split="unseen"))
    with pytest.raises(ValueError, match="training split"):
        ppo.train(ppo.PPOConfig(task="laptop", split="unseen"))


def test_every_shipped_policy_trained_on_seen_objects_only():
    assert manifest(), "the zoo ships no policy"
    for task, entry in manifest().items():
        config = torch.load(ZOO / entry["file"], map_location="cpu", weights_only=True)["config"]
        trains_on_seen_objects_only(config, f"zoo:{task}")


def test_every_parked_run_trains_on_seen_objects_only():
    for record in sorted(IN_PROGRESS.glob("*/run.json")):
        trains_on_seen_objects_only(json.loads(record.read_text())["config"], str(record.parent.name))


def test_the_check_catches_an_unseen_training_object():
    unseen = list_objects("laptop", "unseen")[0].name
    with pytest.raises(AssertionError, match="unseen objects"):
        trains_on_seen_objects_only({"task": "laptop", "split": "seen", "objects": unseen}, "a run")
    with pytest.raises(AssertionError, match="unseen split"):
        trains_on_seen_objects_only({"task": "laptop", "split": "unseen"}, "a run")
