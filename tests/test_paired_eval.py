"""benchmarks/rl/paired_eval.py: the statistics of RL against its student, checked against numbers worked by hand,
and its clear errors (the evaluations themselves are ``rl.evaluate``'s, tested in test_ppo)."""

import json
import math
from pathlib import Path

import pytest


def fake_eval(per_object: dict, k: int) -> dict:
    """An ``evaluate`` result with the given success per object, k episodes each."""
    return {"episodes_per_object": k, "success_rate": sum(per_object.values()) / len(per_object),
            "objects": {name: {"success_rate": p} for name, p in per_object.items()}}


def test_success_and_its_object_stratified_standard_error(load_benchmark):
    bench = load_benchmark("paired_eval")
    # two objects, 4 episodes each, at 0.5 and 1.0: se = sqrt(0.5 * 0.5 / 4 + 0) / 2 = 0.125
    stats = bench.split_stats(fake_eval({"a": 0.5, "b": 1.0}, 4))
    assert stats["success"] == 0.75 and stats["se"] == pytest.approx(0.125)
    assert stats["objects"] == {"a": 0.5, "b": 1.0}
    # every object always or never succeeding: no sampling error at all
    assert bench.split_stats(fake_eval({"a": 0.0, "b": 1.0}, 10))["se"] == 0.0


def test_rl_minus_student_per_split_and_over_seeds(load_benchmark):
    bench = load_benchmark("paired_eval")
    student = {s: bench.split_stats(fake_eval({"a": 0.5, "b": 1.0}, 4)) for s in bench.SPLITS}
    rl = {"seen": bench.split_stats(fake_eval({"a": 1.0, "b": 1.0}, 4)),
          "unseen": bench.split_stats(fake_eval({"a": 0.5, "b": 0.5}, 4))}
    delta = bench.compare(student, rl)
    assert delta["seen"]["value"] == pytest.approx(0.25) and delta["seen"]["se"] == pytest.approx(0.125)
    # unseen: 0.5 - 0.75, se = hypot(0.125, sqrt(2 * 0.0625) / 2)
    assert delta["unseen"]["value"] == pytest.approx(-0.25)
    assert delta["unseen"]["se"] == pytest.approx(math.hypot(0.125, math.sqrt(0.125) / 2))
    rows = [{"task": "laptop", "recipe": "r", "seed": seed, "rl_frames": 10, "student": student, "rl": rl,
             "delta": delta} for seed in (0, 1)]
    entry, = bench.summarise(rows)
    assert entry["seeds"] == [0, 1] and entry["seen"]["delta"] == pytest.approx(0.25)
    assert entry["seen"]["student"] == 0.75 and entry["seen"]["rl"] == 1.0
    # two seeds with se 0.125 each: the mean's se is sqrt(2) * 0.125 / 2
    assert entry["seen"]["delta_se"] == pytest.approx(math.sqrt(2) * 0.125 / 2)


def test_unknown_run_sets_and_missing_checkpoints_are_named(tmp_path, load_benchmark, capsys):
    bench = load_benchmark("paired_eval")
    run_set = {"task": "laptop", "obs": "cloud", "recipe": "student_anchored", "student": {"task": "laptop"},
               "per_seed": [{"seed": 0}], "command": "python benchmarks/rl/curriculum_runs.py ..."}
    (tmp_path / "laptop_cloud_student_anchored.json").write_text(json.dumps(run_set))
    (tmp_path / "laptop_state_bc.json").write_text(json.dumps({**run_set, "obs": "state", "student": None}))
    assert [r["recipe"] for r in bench.run_sets(None, tmp_path)] == ["student_anchored"]  # a student's runs only
    with pytest.raises(ValueError, match="unknown run set.*laptop_state_bc.*valid: laptop_cloud_student_anchored"):
        bench.run_sets(["laptop_state_bc"], tmp_path)
    with pytest.raises(FileNotFoundError, match="RL checkpoint not found.*laptop_cloud_student_anchored_s0"):
        bench.checkpoints(run_set, tmp_path / "runs")
    with pytest.raises(SystemExit) as stop:  # argparse refuses it (the shared option's "min"), naming the flag
        bench.main(["--eval-episodes", "0"])
    assert stop.value.code == 2 and "argument --eval-episodes: must be >= 1, got 0" in capsys.readouterr().err


def test_re_evaluating_one_run_set_keeps_the_others_with_their_provenance(load_benchmark):
    """``--run-sets``: the rows of the run sets named are replaced, every other row is kept with the command and
    machine that measured it (the earlier file's where a row has none); other episodes or seed are refused."""
    bench = load_benchmark("paired_eval")
    previous = {"episodes_per_object": 10, "eval_seed": 1000, "command": "old cmd", "machine": {"cpu": "Xeon"},
                "runs": [{"task": "laptop", "recipe": "a", "seed": s, "rl_frames": 100} for s in (0, 1)]
                + [{"task": "toilet", "recipe": "a", "seed": 0, "rl_frames": 50, "command": "older",
                    "machine": {"cpu": "i7"}}]}
    fresh = [{"task": "laptop", "recipe": "a", "seed": 0, "rl_frames": 700, "command": "new",
              "machine": {"cpu": "EPYC"}}]
    rows = bench.merge_rows(previous, fresh, 10, 1000)
    assert [(r["task"], r["seed"], r["rl_frames"], r["command"]) for r in rows] == [
        ("laptop", 0, 700, "new"), ("toilet", 0, 50, "older")]  # laptop's old seed 1 went with its run set
    assert rows[1]["machine"] == {"cpu": "i7"}
    previous["runs"] = previous["runs"][:1]
    assert bench.merge_rows(previous, [], 10, 1000)[0]["machine"] == {"cpu": "Xeon"}
    with pytest.raises(ValueError, match="10 episodes per object at seed 1000, not 20 at 1000"):
        bench.merge_rows(previous, fresh, 20, 1000)


def test_evaluate_many_evaluates_each_pair_once_and_reads_the_cache_back(tmp_path, monkeypatch):
    """Duplicate (checkpoint, split) pairs are evaluated once; each result is cached next to its checkpoint, named by
    split, episodes and seed, and a second call evaluates nothing."""
    from dexart_lite.rl import evaluate

    calls = []

    def fake(path, split, episodes, seed):
        calls.append((path, split))
        return {"checkpoint": path, "split": split, "episodes_per_object": episodes, "seed": seed}

    monkeypatch.setattr(evaluate, "evaluate_checkpoint", fake)
    a, b = str(tmp_path / "a" / "checkpoint.pt"), str(tmp_path / "b" / "checkpoint.pt")
    work = [(a, "seen"), (b, "seen"), (a, "seen"), (a, "unseen")]
    first = evaluate.evaluate_many(work, 7, 1000)
    assert sorted(calls) == sorted({*work}) and len(first) == 3
    assert first[(a, "unseen")]["split"] == "unseen" and (tmp_path / "a" / "heldout_unseen_e7_seed1000.json").exists()
    assert evaluate.evaluate_many(work, 7, 1000) == first and len(calls) == 3  # all read back
    evaluate.evaluate_many([(a, "seen")], 7, 1001)  # another seed is another evaluation
    assert len(calls) == 4
    # a checkpoint written after its cache (the run trained on) is evaluated again
    import os
    Path(b).write_bytes(b"newer")
    cache = tmp_path / "b" / "heldout_seen_e7_seed1000.json"
    os.utime(cache, (1, 1))
    evaluate.evaluate_many([(b, "seen"), (a, "seen")], 7, 1000)
    assert calls[4:] == [(b, "seen")]


def test_return_vs_success_splits_returns_and_terms_by_outcome(load_benchmark):
    """benchmarks/rl/return_vs_success.py's summary: means over all episodes, the successes and the failures, worked
    by hand for three episodes."""
    bench = load_benchmark("return_vs_success")
    episodes = [
        {"success": True, "return": 300.0, "success_step": 80, "q": 1.9, "terms": {"contact": 10.0, "bonus": 290.0}},
        {"success": True, "return": 200.0, "success_step": 120, "q": 1.6, "terms": {"contact": 20.0, "bonus": 180.0}},
        {"success": False, "return": 40.0, "success_step": None, "q": None, "terms": {"contact": 40.0, "bonus": 0.0}}]
    row = bench.summary("p", episodes, "ckpt.pt", 100)
    assert row["success_rate"] == pytest.approx(2 / 3) and row["mean_return"] == pytest.approx(180.0)
    assert row["mean_return_success"] == 250.0 and row["mean_return_failure"] == 40.0
    assert row["mean_success_step"] == 100.0 and row["mean_q_at_success"] == pytest.approx(1.75)
    assert row["mean_bonus"] == 235.0 and row["terms"]["failure"] == {"contact": 40.0, "bonus": 0.0}
    assert row["terms"]["all"]["contact"] == pytest.approx(70 / 3)
    # no failures: their means are None, not NaN
    assert bench.summary("p", episodes[:1])["mean_return_failure"] is None


def test_return_vs_success_writes_the_fields_it_documents(tmp_path, capsys, load_benchmark):
    """Fast mode: the expert alone on one object, one episode; a checkpoint of another task is refused."""
    bench = load_benchmark("return_vs_success")
    path = tmp_path / "r.json"
    result = bench.main(["--task", "faucet", "--json", str(path)])
    assert json.loads(path.read_text()) == json.loads(json.dumps(result))
    row, = result["policies"]
    assert row["episodes"] == 1 and {"command", "machine", "expert_noise", "split"} <= result.keys()
    assert result["reward"] == "dexart" and set(row["terms"]["all"]) >= {"reach", "contact", "bonus"}
    with pytest.raises(SystemExit):  # argparse: the shared --task flag names the tasks
        bench.main(["--task", "sink"])
    assert "invalid choice: 'sink' (choose from 'faucet', 'bucket', 'laptop', 'toilet')" in capsys.readouterr().err
    with pytest.raises(ValueError, match="unknown reward 'dense'; valid choices: dexart, shaped, capped, flat"):
        bench.main(["--task", "faucet", "--reward", "dense"])


def test_curve_compare_averages_each_frame_window_by_hand(tmp_path, load_benchmark):
    """benchmarks/rl/curve_compare.py: window means over the batches with lo < frames <= hi (NaN and missing
    values skipped, None for an empty window), seeds pooled and apart; a run without a key is refused by name."""
    bench = load_benchmark("curve_compare")
    curve = lambda pairs: [{"frames": f, "success_rate": s, "bc_weight": 1.0} for f, s in pairs]  # noqa: E731
    result = {"task": "faucet", "obs": "state", "recipe": "r", "settings": {"reward": "capped"},
              "per_seed": [{"seed": 0, "curve": curve([(100, 1.0), (200, 0.5), (300, float("nan")), (400, 0.0)])},
                           {"seed": 1, "curve": curve([(100, 0.0), (200, 0.5), (400, 1.0)])}]}
    path = tmp_path / "faucet_state_r.json"
    path.write_text(json.dumps(result))
    out = bench.main([str(path), "--keys", "success_rate", "--windows", "0", "200", "400", "1000",
                      "--png", str(tmp_path / "c.png"), "--json", str(tmp_path / "c.json")])
    rows = {(r["seed"], r["window"]): r["success_rate"] for r in out["table"]}
    assert rows[("all", "0-200")] == pytest.approx((1.0 + 0.5 + 0.0 + 0.5) / 4)  # frames 100, 200 of both seeds
    assert rows[(0, "0-200")] == 0.75 and rows[(1, "0-200")] == 0.25
    assert rows[(0, "200-400")] == 0.0 and rows[(1, "200-400")] == 1.0  # frame 300's NaN skipped, 400 kept
    assert rows[("all", "200-400")] == 0.5 and rows[("all", "400-1k")] is None
    out = bench.main([str(path), "--keys", "success_rate", "--windows", "0", "400", "1000"])
    assert [r["success_rate"] for r in out["table"] if r["seed"] == "all"] == [0.5, None]
    assert out["runs"][0]["reward"] == "capped" and (tmp_path / "c.png").stat().st_size > 0
    assert json.loads((tmp_path / "c.json").read_text())["keys"] == ["success_rate"]
    with pytest.raises(ValueError, match=r"no curve field \['episode_return'\]"):
        bench.main([str(path), "--keys", "episode_return"])
    with pytest.raises(ValueError, match="increasing"):
        bench.main([str(path), "--windows", "300", "0"])


def test_return_vs_success_scores_a_policy_on_the_reward_asked_whatever_it_trained_on(tmp_path, load_benchmark):
    """A tiny state policy trained on reward="capped" runs beside the expert on the same resets, scored on DexArt's
    reward (``--reward dexart``): its row names its checkpoint and frames."""
    import dataclasses

    from dexart_lite.rl import ppo

    cfg = dataclasses.replace(ppo.PPOConfig(), task="faucet", obs="state", reward="capped", frames=200,
                              frames_per_batch=100, minibatch=100, epochs=1, max_episode_steps=20, eval_episodes=1,
                              workers=0, progress=False, out=str(tmp_path / "run"))
    ppo.train(cfg)
    checkpoint = str(tmp_path / "run" / ppo.CHECKPOINT)
    result = load_benchmark("return_vs_success").main(["--task", "faucet", "--policy", checkpoint,
                                                       "--reward", "dexart"])
    expert, policy = result["policies"]
    assert result["reward"] == "dexart" and policy["checkpoint"] == checkpoint and policy["frames"] == 200
    assert policy["episodes"] == expert["episodes"] == 1


# ---------------------------------------------------------------- benchmarks/rl/checkpoint_sweep.py
def test_a_checkpoint_sweep_summarises_each_series_against_its_start(load_benchmark):
    """Per series: the RL checkpoints' mean, swing and gain over the start, with se's worked by hand."""
    bench = load_benchmark("checkpoint_sweep")
    stats = lambda p, se: {"success": p, "se": se}  # noqa: E731 (one split's entry)
    point = lambda f, seen, unseen: {"frames": f, "seen": stats(seen, 0.03), "unseen": stats(unseen, 0.04)}  # noqa: E731
    series = {"s0": {"start": point(0, 0.4, 0.2), "checkpoints": [point(8, 0.5, 0.2), point(9, 0.3, 0.3)]},
              "s1": {"start": None, "checkpoints": [point(5, 0.6, 0.1)]}}
    summary = bench.summarise(series)
    s0 = summary["series"]["s0"]["seen"]
    assert s0["mean"] == pytest.approx(0.4) and s0["swing"] == pytest.approx(0.2) and s0["min"] == 0.3
    assert s0["gain"] == pytest.approx(0.0)
    # two checkpoints of se 0.03: the mean's se is sqrt(2) * 0.03 / 2, and the start's 0.03 adds in quadrature
    assert s0["mean_se"] == pytest.approx(math.sqrt(2) * 0.03 / 2)
    assert s0["gain_se"] == pytest.approx(math.hypot(math.sqrt(2) * 0.03 / 2, 0.03))
    assert "gain" not in summary["series"]["s1"]["seen"]  # no start: no gain, and not in the mean gain
    assert summary["unseen_gain"] == pytest.approx(0.05)
    later = bench.summarise({"s0": series["s0"]}, from_frames=9)["series"]["s0"]["seen"]  # the checkpoint at 8 frames left out
    assert later["mean"] == pytest.approx(0.3) and later["gain"] == pytest.approx(-0.1) and later["swing"] == 0
    with pytest.raises(ValueError, match="series s1 has no checkpoint of at least 9 frames"):
        bench.summarise({"s1": series["s1"]}, from_frames=9)


def test_a_checkpoint_sweep_reads_committed_checkpoints_from_git_with_their_evaluations(
        tmp_path, monkeypatch, load_benchmark):
    """``REV:path`` checkpoints come out of git with the held-out evaluations committed beside them, which are read
    back (nothing is evaluated again: evaluating would raise here) and reported as they were measured. The repository
    is one made here: a student and an RL checkpoint (two shipped policies) with their evaluations, committed."""
    import shutil
    import subprocess

    from dexart_lite.rl import evaluate
    from dexart_lite.rl.checkpoint import load_checkpoint
    from dexart_lite.zoo import resolve as zoo_path

    bench = load_benchmark("checkpoint_sweep")
    repo = tmp_path / "repo"
    successes = {"student": (0.4, 0.3), "rl": (0.7, 0.5)}
    for folder, task in (("student", "faucet"), ("rl", "laptop")):
        (repo / folder).mkdir(parents=True)
        shutil.copy(zoo_path(f"zoo:{task}"), repo / folder / "checkpoint.pt")
        frames = load_checkpoint(repo / folder / "checkpoint.pt")["frames"]
        for split, success in zip(("seen", "unseen"), successes[folder]):
            result = {"task": task, "frames": frames, "success_rate": success, "episodes_per_object": 10,
                      "objects": {"a": {"success_rate": success}, "b": {"success_rate": success}}}
            (repo / folder / f"heldout_{split}_e10_seed1000.json").write_text(json.dumps(result))
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(repo)]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "runs"], check=True)
    monkeypatch.setattr(bench, "REPO", repo)

    def boom(*args, **kwargs):
        raise AssertionError("a committed evaluation was run again")

    monkeypatch.setattr(evaluate, "evaluate_checkpoint", boom)
    out = bench.main(["s0=HEAD:rl/checkpoint.pt", "--start", "s0=HEAD:student/checkpoint.pt",
                      "--cache", str(tmp_path / "cache"), "--json", str(tmp_path / "sweep.json")])
    committed = json.loads((repo / "rl" / "heldout_seen_e10_seed1000.json").read_text())
    s0 = out["series"]["s0"]
    assert s0["start"]["frames"] == 0 and s0["checkpoints"][0]["frames"] == committed["frames"] > 0
    assert s0["checkpoints"][0]["seen"]["success"] == committed["success_rate"] == 0.7
    assert out["summary"]["seen_gain"] == pytest.approx(0.7 - 0.4)
    assert out["summary"]["unseen_gain"] == pytest.approx(0.5 - 0.3)
    assert (tmp_path / "sweep.png").is_file()


def test_a_checkpoint_sweep_leaves_out_committed_evaluations_of_another_checkpoint(tmp_path, monkeypatch,
                                                                                     load_benchmark, capsys):
    """A run committed its checkpoint before its held-out files were evaluated again: ``REV:path`` extracts only the
    evaluations whose ``frames`` are the checkpoint's, so a stale one is evaluated anew, not read back."""
    import subprocess

    bench = load_benchmark("checkpoint_sweep")
    repo = tmp_path / "repo"
    (repo / "run").mkdir(parents=True)
    (repo / "run" / "checkpoint.pt").write_bytes(b"weights at 900 frames")
    for split, frames in (("seen", 900), ("unseen", 600)):  # the unseen one measured an older checkpoint
        (repo / "run" / f"heldout_{split}_e10_seed1000.json").write_text(json.dumps({"frames": frames}))
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-C", str(repo)]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "."], check=True)
    subprocess.run([*git, "commit", "-qm", "run"], check=True)
    monkeypatch.setattr(bench, "REPO", repo)
    monkeypatch.setattr(bench, "checkpoint_frames", lambda path: 900)
    target = bench.resolve("HEAD:run/checkpoint.pt", tmp_path / "cache")
    assert target.read_bytes() == b"weights at 900 frames"
    assert json.loads((target.parent / "heldout_seen_e10_seed1000.json").read_text()) == {"frames": 900}
    assert not (target.parent / "heldout_unseen_e10_seed1000.json").exists()
    assert "at 600 frames, this one has 900" in capsys.readouterr().out


def test_a_checkpoint_sweep_names_bad_arguments(tmp_path, load_benchmark):
    bench = load_benchmark("checkpoint_sweep")
    with pytest.raises(ValueError, match="--start for series without checkpoints: s9"):
        bench.main([f"s0={tmp_path}/a.pt", "--start", f"s9={tmp_path}/b.pt", "--json", str(tmp_path / "x.json")])
    with pytest.raises(FileNotFoundError, match="checkpoint not found.*REV:path"):
        bench.resolve(str(tmp_path / "missing.pt"), tmp_path)
    with pytest.raises(FileNotFoundError, match="is not in git"):
        bench.resolve("HEAD:no/such/checkpoint.pt", tmp_path)
    import argparse
    with pytest.raises(argparse.ArgumentTypeError, match="SERIES=CHECKPOINT"):
        bench.parse_spec("just_a_path.pt")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process tree from /proc (Linux)")
def test_kill_on_an_evaluate_many_caller_leaves_no_evaluation_worker_behind(tmp_path):
    """``kill`` (SIGTERM) on a process in ``evaluate_many(..., jobs=2)`` (``paired_eval.py``) ends its two spawned
    evaluation workers with it, each busy with 1000 episodes per object, and writes no result: a stopped
    evaluation must not go on unwatched on the machine's cores."""
    import shutil
    import sys

    from tests.processes import descendants, kill_once_started

    checkpoint = tmp_path / "laptop" / "checkpoint.pt"  # results are cached beside it: a copy keeps the zoo clean
    checkpoint.parent.mkdir()
    shutil.copy(Path(__file__).resolve().parent.parent / "dexart_lite" / "zoo" / "laptop.pt", checkpoint)
    code = ("from dexart_lite.rl.evaluate import evaluate_many; "
            f"evaluate_many([({str(checkpoint)!r}, 'seen'), ({str(checkpoint)!r}, 'unseen')], 1000, 1000, jobs=2)")

    def both_workers_spawned(pid: int) -> bool:  # the pool's workers, not its resource tracker
        found = 0
        for child in descendants(pid):
            try:
                found += b"spawn_main" in Path(f"/proc/{child}/cmdline").read_bytes()
            except OSError:  # ended while we looked
                pass
        return found >= 2

    status = kill_once_started([sys.executable, "-c", code], both_workers_spawned, "evaluation workers",
                               tmp_path / "stderr.txt", timeout=120)
    assert status != 0
    assert not list(checkpoint.parent.glob("heldout_*.json"))


# ---------------------------------------------------------------- benchmarks/rl/select_checkpoint.py
def test_the_checkpoint_chosen_on_seen_validation_episodes_is_the_one_evaluated_held_out(tmp_path, monkeypatch,
                                                                                        load_benchmark):
    """The choice sees only seen objects at the validation seed; the pick (ties: more frames), the last candidate
    and the start, and nothing else, get the held-out evaluation on both splits at the held-out seed."""
    bench = load_benchmark("select_checkpoint")
    frames = {"a0": 100, "a1": 200, "a2": 300, "b0": 100, "b1": 200, "sa": 0, "sb": 0}
    validation = {"a0": 0.6, "a1": 0.8, "a2": 0.7, "b0": 0.5, "b1": 0.5}  # s0 picks a1; s1 a tie, b1 the later
    files = {}
    for name in frames:
        files[name] = tmp_path / name / "checkpoint.pt"
        files[name].parent.mkdir()
        files[name].write_bytes(b"weights")
    name_of = {str(path): name for name, path in files.items()}
    calls = []

    def fake_evaluate_many(work, episodes, seed, jobs=1):
        calls.append((sorted((name_of[c], s) for c, s in work), episodes, seed))
        p = (lambda n, s: validation[n]) if seed == 100 else (lambda n, s: 0.9 if s == "seen" else 0.3)
        return {(c, s): {**fake_eval({"o": p(name_of[c], s)}, episodes), "frames": frames[name_of[c]]}
                for c, s in work}

    monkeypatch.setattr(bench, "evaluate_many", fake_evaluate_many)
    out = bench.main(["--start", f"s0={files['sa']}", f"s1={files['sb']}", "--select-seed", "100",
                      "--select-episodes", "4", "--seed", "7919", "--eval-episodes", "10",
                      "--json", str(tmp_path / "picked.json"), "--",
                      *(f"s0={files[n]}" for n in ("a2", "a0", "a1")), *(f"s1={files[n]}" for n in ("b0", "b1"))])
    (chosen, k, seed), (held, k_held, seed_held) = calls
    assert chosen == sorted((n, "seen") for n in validation) and (k, seed) == (4, 100)
    assert set(held) == {(n, s) for n in ("sa", "a1", "a2", "sb", "b1") for s in ("seen", "unseen")}
    assert (k_held, seed_held) == (10, 7919)
    s0, s1 = out["series"]["s0"], out["series"]["s1"]
    assert [c["frames"] for c in s0["candidates"]] == [100, 200, 300]  # sorted by frames, as named or not
    assert s0["picked"]["checkpoint"] == str(files["a1"]) and s0["last"]["frames"] == 300
    assert s1["picked"]["frames"] == s1["last"]["frames"] == 200
    assert s0["picked"]["unseen"]["success"] == 0.3 and s0["start"]["frames"] == 0
    assert (tmp_path / "picked.png").is_file()


def test_a_checkpoint_choice_summarises_picked_last_and_start_over_series(load_benchmark):
    bench = load_benchmark("select_checkpoint")
    stats = lambda p, se: {"success": p, "se": se}  # noqa: E731
    entry = lambda seen, unseen: {"seen": stats(seen, 0.03), "unseen": stats(unseen, 0.04)}  # noqa: E731
    series = {"s0": {"start": entry(0.6, 0.6), "picked": entry(0.9, 0.7), "last": entry(0.8, 0.7)},
              "s1": {"start": entry(0.6, 0.5), "picked": entry(0.7, 0.8), "last": entry(0.7, 0.6)}}
    seen, unseen = (bench.summarise(series)[s] for s in ("seen", "unseen"))
    assert seen["picked"] == pytest.approx(0.8) and seen["last"] == pytest.approx(0.75)
    assert seen["picked_minus_start"] == pytest.approx(0.2) and seen["picked_minus_last"] == pytest.approx(0.05)
    assert unseen["last_minus_start"] == pytest.approx(0.1)
    # two series of se 0.03: the mean's se is sqrt(2) * 0.03 / 2; a difference of two such means adds in quadrature
    assert seen["picked_se"] == pytest.approx(math.sqrt(2) * 0.03 / 2)
    assert seen["picked_minus_start_se"] == pytest.approx(0.03)
    with pytest.raises(ValueError, match="no candidate"):
        bench.pick([])
    tie = [{"frames": 5, "validation": stats(0.5, 0)}, {"frames": 9, "validation": stats(0.5, 0)},
           {"frames": 7, "validation": stats(0.4, 0)}]
    assert bench.pick(tie)["frames"] == 9


def test_a_checkpoint_choice_names_bad_arguments(tmp_path, load_benchmark):
    bench = load_benchmark("select_checkpoint")
    ckpt = tmp_path / "c.pt"
    ckpt.write_bytes(b"weights")
    base = ["--json", str(tmp_path / "x.json"), "--start", f"s0={ckpt}", "--", f"s0={ckpt}"]
    with pytest.raises(ValueError, match="--select-seed must differ from the held-out --seed"):
        bench.main(["--select-seed", "1000", *base])
    with pytest.raises(ValueError, match="--select-episodes must be >= 1"):
        bench.main(["--select-episodes", "0", *base])
    with pytest.raises(ValueError, match="every series needs one --start.*series s0, s1, starts s0"):
        bench.main([*base, f"s1={ckpt}"])
