"""The per-task recipes (``dexart_lite/rl/recipes.py``): each is the measured run set behind its headline cell, and
``dexart-lite train --recipe`` runs the whole pipeline (fast mode: a smoke run, set in conftest)."""

import json

import pytest

from dexart_lite import cli
from dexart_lite.rl import recipes
from dexart_lite.rl.evaluate import TEST_SEEDS


def test_train_recipe_runs_demonstrations_student_rl_and_the_final_evaluation_then_reads_back(tmp_path):
    out = tmp_path / "laptop"
    argv = ["train", "--task", "laptop", "--recipe", "experts", "--set", "frames=400", "student.rounds=1",
            "--out", str(out)]
    assert cli.main(argv) == 0
    result = json.loads((out / "recipe.json").read_text())
    learner, student = result["learner"]["config"], result["student"]["config"]
    assert result["learner"]["frames"] == 400 and learner["init_from"] == str(out / "student" / "checkpoint.pt")
    assert learner["reward"] == "flat" and learner["anchor_floor"] == 0.1 and student["rounds"] == 1
    assert result["final_evaluation"]["env_seed"] == TEST_SEEDS[0]
    assert set(result["final_evaluation"]) >= {"seen", "unseen"}
    assert "RL (±" in (out / "report.md").read_text()
    stamp = (out / "rl" / "checkpoint.pt").stat().st_mtime_ns
    assert cli.main(argv) == 0  # the same command again: both stages are read back, nothing trains
    assert (out / "rl" / "checkpoint.pt").stat().st_mtime_ns == stamp


def test_each_recipe_is_the_run_set_its_cell_was_measured_with(load_benchmark):
    """The package's recipe and the benchmark's run set of the same name have the same learner settings and the same
    student (the run set's student step: the headline student's settings plus its variant's)."""
    runs = load_benchmark("curriculum_runs")
    for task, named in recipes.RECIPES.items():
        r = named["experts"]
        assert {k: v for k, v in runs.RECIPES[r.run_set].items() if k != "student"} == {
            k: v for k, v in r.learner.items() if k not in ("frames", "eval_episodes")}, task
        variant = runs.RECIPES[r.run_set]["student"]
        overrides = json.loads((runs.RESULTS.parents[1] / "students" / runs.STUDENTS[task]).read_text())["overrides"]
        expected = {**overrides, **(runs.STUDENT_VARIANTS[variant] if variant is not True else {})}
        expected.pop("threads", None)  # how many cores, not a setting of the student
        assert expected == r.student, task


def test_overrides_go_to_the_stage_that_has_the_field_and_bad_ones_are_named(tmp_path, monkeypatch):
    monkeypatch.setenv("DEXART_LITE_FAST", "0")
    student, learner = recipes.configs("toilet", "experts", tmp_path, ["lr=1e-4", "drop_failed=false",
                                                                        "student.seed=3", "seed=5"])
    assert learner.lr == 1e-4 and learner.curriculum == "reverse" and learner.frames == 964_000
    assert student.drop_failed is False and student.seed == 3 and learner.seed == 5
    assert student.demo_episodes_per_object == 9 and learner.init_from == str(tmp_path / "student" / "checkpoint.pt")
    with pytest.raises(ValueError, match="PPOConfig field 'no_such_field'"):
        recipes.configs("toilet", "experts", tmp_path, ["no_such_field=1"])
    with pytest.raises(ValueError, match="unknown toilet recipe 'fastest'; valid choices: experts"):
        recipes.recipe("toilet", "fastest")
    assert cli.main(["train", "--recipe", "experts", "--out", str(tmp_path)]) == 2  # no --task: one line, exit 2
