"""The one evaluation protocol: disjoint validation and test seeds, the headline chosen by a rule on validation
results of seen objects alone, and a cell's ± as the standard error over training seeds."""

import math
from pathlib import Path

import pytest

from dexart_lite.rl import evaluate


def test_validation_and_test_seeds_are_disjoint_and_each_phase_refuses_the_others_seeds():
    assert not set(evaluate.VALIDATION_SEEDS) & set(evaluate.TEST_SEEDS)
    assert evaluate.check_phase_seed("validation", evaluate.VALIDATION_SEEDS[0]) == evaluate.VALIDATION_SEEDS[0]
    with pytest.raises(ValueError, match=f"env seed {evaluate.TEST_SEEDS[0]} is not a validation seed; validation "
                                         "seeds: 100, 1000"):
        evaluate.check_phase_seed("validation", evaluate.TEST_SEEDS[0])
    with pytest.raises(ValueError, match="not a test seed"):
        evaluate.check_phase_seed("test", 100)
    with pytest.raises(ValueError, match="phase.*validation, test"):
        evaluate.check_phase_seed("training", 100)


def test_a_cell_is_the_mean_over_seeds_with_the_standard_error_over_them():
    cell = evaluate.over_seeds([0.9, 0.6, 0.75])
    # sample std of (0.9, 0.6, 0.75) is 0.15; se = 0.15 / sqrt(3)
    assert cell["mean"] == pytest.approx(0.75) and cell["se"] == pytest.approx(0.15 / math.sqrt(3))
    assert cell["per_seed"] == [0.9, 0.6, 0.75] and cell["seeds"] == 3
    assert evaluate.over_seeds([0.4])["se"] == 0.0
    with pytest.raises(ValueError, match="no seed"):
        evaluate.over_seeds([])


class UnreadableTestResults(dict):
    """A candidate's test-seed results: reading them is what the rule must never do."""

    def __getitem__(self, key):
        raise AssertionError("the headline rule read a test-seed result")

    get = __getitem__


def candidate(name: str, frames: list[int], seen: list[float], unseen: list[float]) -> dict:
    return {"name": name, "frames": frames, "validation": {"seen": seen, "unseen": unseen},
            "test": UnreadableTestResults(seen=[1.0], unseen=[1.0])}


def test_the_headline_rule_picks_the_best_validation_mean_on_seen_objects_within_the_budget():
    runs = [candidate("long", [3_000_000, 3_000_000], [0.95, 0.95], [0.9, 0.9]),   # best, but over the budget
            candidate("wide", [1_000_000, 900_000], [0.8, 0.7], [0.1, 0.1]),
            candidate("unseen_best", [500_000, 500_000], [0.7, 0.7], [0.99, 0.99]),  # unseen never chooses
            candidate("tie_longer", [1_500_000, 1_500_000], [0.75, 0.75], [0.5, 0.5])]
    assert evaluate.choose_headline(runs, 2_000_000)["name"] == "wide"  # 0.75, and fewer frames than tie_longer
    assert evaluate.choose_headline(runs, 4_000_000)["name"] == "long"
    with pytest.raises(ValueError, match="no candidate within the budget of 100 frames"):
        evaluate.choose_headline(runs, 100)


def test_a_script_that_chooses_refuses_a_test_seed(tmp_path, load_benchmark):
    """select_checkpoint.py picks a checkpoint: its validation episodes must be at a validation seed."""
    bench = load_benchmark("select_checkpoint")
    test_seed = str(evaluate.TEST_SEEDS[0])
    with pytest.raises(ValueError, match=f"env seed {test_seed} is not a validation seed"):
        bench.main([f"s0={tmp_path}/a.pt", "--start", f"s0={tmp_path}/b.pt", "--select-seed", test_seed,
                    "--seed", "1000", "--json", str(tmp_path / "x.json")])


def test_the_expert_is_evaluated_on_the_protocols_episodes_and_replays():
    first = evaluate.evaluate_expert("laptop", "unseen", 1, evaluate.TEST_SEEDS[0])
    again = evaluate.evaluate_expert("laptop", "unseen", 1, evaluate.TEST_SEEDS[0])
    assert first["episodes"] == len(first["objects"]) == 6 and first["seed"] == evaluate.TEST_SEEDS[0]
    assert first["objects"] == again["objects"] and first["success_rate"] > 0.5  # the expert opens unseen laptops


def test_a_test_cell_evaluates_each_training_seed_at_the_test_seed_and_counts_its_simulator_steps(
        tmp_path, monkeypatch, load_benchmark):
    """Two students (the zoo's faucet policy, copied per seed): the cell is the mean over seeds with their se, every
    evaluation ran at the test seed with the protocol's episodes, and the steps are the distillation's."""
    import json
    import shutil

    from dexart_lite.objects import list_objects
    from dexart_lite.rl.checkpoint import load_checkpoint
    from dexart_lite.zoo import resolve as zoo_file

    bench = load_benchmark("final_evaluation")
    files = {}
    for seed in (0, 1):
        files[seed] = tmp_path / f"s{seed}" / "checkpoint.pt"
        files[seed].parent.mkdir()
        shutil.copy(zoo_file("zoo:faucet"), files[seed])
    seen = []

    def fake_evaluation(path, split, episodes, seed, device="cpu"):
        seen.append((episodes, seed))
        success = {"s0": 0.8, "s1": 0.6}[Path(path).parent.name] - (0.2 if split == "unseen" else 0.0)
        return {"task": "faucet", "split": split, "frames": 0, "success_rate": success, "episodes_per_object": episodes,
                "objects": {o.name: {"success_rate": success} for o in list_objects("faucet", split)}}

    monkeypatch.setattr(evaluate, "evaluate_checkpoint", fake_evaluation)
    out = bench.main(["--task", "faucet", "--column", "student", "--checkpoints", f"0={files[0]}", f"1={files[1]}",
                      "--source", "faucet_students.json", "--json", str(tmp_path / "cell.json")])
    assert set(seen) == {(evaluate.EPISODES_PER_OBJECT, evaluate.TEST_SEEDS[0])} and len(seen) == 4
    assert out["seen"]["mean"] == pytest.approx(0.7) and out["seen"]["se"] == pytest.approx(0.1)  # std 0.141 / sqrt 2
    assert out["unseen"]["per_seed"] == pytest.approx([0.6, 0.4])
    assert out["unseen"]["templates"]["held_out_bands"]["success"] == pytest.approx(0.5)  # per object, mean of seeds
    last = load_checkpoint(files[0])["history"][-1]
    assert out["steps"][0]["demo_frames"] == last["expert_frames"] + last["student_frames"] == out["steps"][0][
        "steps_in_all"]
    assert json.loads((tmp_path / "cell.json").read_text())["env_seed"] == evaluate.TEST_SEEDS[0]
    assert out["source"] == "faucet_students.json"
    with pytest.raises(ValueError, match="--task laptop but the checkpoints are of faucet"):
        bench.main(["--task", "laptop", "--column", "rl", "--checkpoints", f"0={files[0]}", "--source", "x.json",
                    "--json", str(tmp_path / "x.json")])
    with pytest.raises(ValueError, match="--checkpoints and --source are needed"):
        bench.main(["--task", "faucet", "--column", "rl", "--json", str(tmp_path / "x.json")])


def test_success_by_template_comes_from_the_objects_metadata():
    """Per template and, for the unseen split, the held-out-band half (templates the seen split has) and the
    held-out-template half (templates it has not), all read from the catalog."""
    from dexart_lite.objects import list_objects

    unseen = list_objects("toilet", "unseen")
    seen_templates = {o.template for o in list_objects("toilet", "seen")}
    per_object = {o.name: float(o.template in seen_templates) for o in unseen}  # bands succeed, the new template not
    groups = evaluate.by_template("toilet", "unseen", per_object)
    bands = [o for o in unseen if o.template in seen_templates]
    assert groups["held_out_bands"] == {"success": 1.0, "objects": len(bands)}
    assert groups["held_out_template"] == {"success": 0.0, "objects": len(unseen) - len(bands)}
    assert sum(g["objects"] for k, g in groups.items() if k.startswith("template ")) == len(unseen) == 11
    assert "held_out_bands" not in evaluate.by_template("toilet", "seen", {o.name: 1.0 for o in list_objects("toilet", "seen")})
