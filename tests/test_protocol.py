"""The one evaluation protocol: disjoint validation and test seeds, the headline chosen by a rule on validation
results of seen objects alone, and a cell's ± as the standard error over training seeds."""

import math

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
