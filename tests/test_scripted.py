"""Scripted solvers: each task is solvable through the 22-D action interface.

Seeded and short: a few objects per task, one episode each (the full tables come from
``dexart-lite solve``, see ``benchmarks/results/experts/solve_*.json``).
"""

import numpy as np
import pytest

from dexart_lite.envs import make
from dexart_lite.experts import ScriptedPolicy
from dexart_lite.experts.solve import solve


def run_episode(task: str, name: str, seed: int) -> tuple[bool, list[int]]:
    """One scripted episode; returns success (at any step) and the stage after every step."""
    env = make(task, object_names=[name], num_points=32)
    try:
        policy = ScriptedPolicy(env)
        obs, info = env.reset(seed=seed, options={"object": name})
        stages, success, done = [info["stage"]], False, False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            stages.append(info["stage"])
            success, done = success or info["success"], terminated or truncated
        return success, stages
    finally:
        env.close()


def first_steps(stages: list[int]) -> list[int]:
    """The stages in the order they are first reached."""
    return list(dict.fromkeys(stages))


# ----------------------------------------------------------------------------- every task
@pytest.mark.parametrize("task, name, seed", [
    ("faucet", "faucet_87eba23916", 0),     # seen, A: long lever
    ("faucet", "faucet_47affbe3f0", 3),     # seen, B: cross knob
    ("faucet", "faucet_344a20032b", 0),     # unseen, C: wing handle
    ("laptop", "laptop_11cbb00f39", 0),     # seen, A: sharp slab, lid turned -58 degrees
    ("laptop", "laptop_740e7c6eca", 1),     # unseen, C: wedge base, hinge barrel
    ("toilet", "toilet_de041d761d", 1004),  # seen, A: lid edge 0.27 m in front of the robot base
    ("toilet", "toilet_bf73de51fa", 0),     # unseen, C: squarish, tankless
    ("bucket", "bucket_413287b6c4", 1),     # seen, B: tapered
    ("bucket", "bucket_fc5ca27e47", 0),     # unseen, C: square pail, U-bail
])
def test_solver_succeeds(task, name, seed):
    success, stages = run_episode(task, name, seed)
    assert success, f"{name}: stages reached {first_steps(stages)}"


# ----------------------------------------------------------------------------- faucet
def test_faucet_stages_go_2_3():
    """The faucet starts in stage 2: the start pose puts the palm within the 0.2 m reach radius of
    every faucet handle under every placement, so the solver goes 2 -> 3 (never back)."""
    success, stages = run_episode("faucet", "faucet_882419ff33", 4)
    assert success
    assert first_steps(stages) == [2, 3]
    assert stages[-1] == 3


def test_faucet_solve_reports_rates():
    result = solve("faucet", "seen", episodes_per_object=1, object_names=["faucet_fa860352d6"], progress=False)
    assert result["success_per_object"] == {"faucet_fa860352d6": 1.0}
    assert result["success_rate"] == 1.0 and result["mean_max_stage"] == 3.0


# ----------------------------------------------------------------------------- laptop and toilet
@pytest.mark.parametrize("task, name, seed", [("laptop", "laptop_cfd3b8b3b2", 1), ("toilet", "toilet_2ecd7e3a4f", 1)])
def test_lid_stages_go_1_2_3(task, name, seed):
    """Reach (palm farther than 0.2 m laptop / 0.1 m toilet from the lid's grasp point), contact,
    manipulation: a lid episode starts in stage 1 and ends in stage 3 (success terminates it)."""
    success, stages = run_episode(task, name, seed)
    assert success
    assert first_steps(stages) == [1, 2, 3]
    assert stages[0] == 1 and stages[-1] == 3


# ----------------------------------------------------------------------------- bucket
def test_bucket_stages_go_1_2_3():
    """Stage 3 needs >= 3 finger groups on the bail at DexArt's 0.01 N*s: the overhand expert's curled
    fingers and thumb press on the tube once the bucket hangs from them (the hook expert never got there)."""
    success, stages = run_episode("bucket", "bucket_222c59ab44", 3)
    assert success
    assert first_steps(stages) == [1, 2, 3]


def test_bucket_expert_regrasps_a_dropped_bail():
    """Closed loop: the bail knocked back down to lying while the expert carries it up (a slip) sends the
    expert back to its approach, and it grasps and lifts the bucket again within the episode."""
    env = make("bucket", object_names=["bucket_222c59ab44"], num_points=32)
    try:
        policy = ScriptedPolicy(env)
        obs, info = env.reset(seed=3, options={"object": "bucket_222c59ab44"})
        phases, success, dropped, done = [], False, False, False
        while not done:
            obs, _, terminated, truncated, info = env.step(policy(obs))
            phases.append(policy.solver.phase)
            if not dropped and policy.solver.phase == "raise" and env.unwrapped.state.q > -1.2:
                env.unwrapped.objects.set_joint(-np.pi / 2)  # the tube out of the hand, lying again
                dropped, at = True, len(phases)
            success, done = success or (dropped and info["success"]), terminated or truncated
        assert dropped and "approach" in phases[at:], "the expert did not go back for the tube"
        assert success
    finally:
        env.close()


def test_an_expert_of_another_task_is_refused_by_name():
    """``solve(expert=...)`` / ``--expert`` takes the task's own expert or an earlier one of the same task; any
    other name is a one-line error that lists the choices."""
    env = make("bucket", num_points=32)
    try:
        with pytest.raises(ValueError, match="bucket expert 'FaucetSolver'.*OverhandBucketSolver, BucketSolver"):
            ScriptedPolicy(env, "FaucetSolver")
        assert ScriptedPolicy(env, "BucketSolver").expert.__name__ == "BucketSolver"
    finally:
        env.close()


def test_bucket_expert_under_noise_replays(monkeypatch, load_benchmark):
    """The bucket expert's noise curve is reproducible: exploration_noise.py in fast mode (the first seen
    bucket, noise std 0 and 1) gives the same rows twice with the same seed, and the noise-free episode lifts."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("exploration_noise")
    runs = [bench.main(["--task", "bucket", "--splits", "seen", "--seeds", "0"])["rows"] for _ in range(2)]
    keys = ("action_noise", "success_rate", "mean_max_stage", "mean_return", "stage_fractions")
    assert [[r[k] for k in keys] for r in runs[0]] == [[r[k] for k in keys] for r in runs[1]]
    assert runs[0][0]["action_noise"] == 0.0 and runs[0][0]["success_rate"] == 1.0
    assert runs[0][0]["expert"] == "OverhandBucketSolver"


# ----------------------------------------------------------------------------- exploration noise
def test_action_noise_of_ppo_init_breaks_the_solver():
    """``solve(action_noise=...)`` adds N(0, sigma) to each action before the env's clip. With PPO's
    initial std of 1 the solver, which succeeds without noise, no longer lifts the lid
    (``benchmarks/experts/exploration_noise.py`` has the whole sweep)."""
    kwargs = dict(episodes_per_object=1, object_names=["laptop_11cbb00f39"], progress=False)
    clean, noisy = solve("laptop", action_noise=0.0, **kwargs), solve("laptop", action_noise=1.0, **kwargs)
    assert clean["success_rate"] == 1.0 and noisy["success_rate"] == 0.0
    for result in (clean, noisy):
        assert sum(result["stage_fractions"].values()) == pytest.approx(1.0)
    assert noisy["stage_fractions"]["stage3"] == 0.0 < clean["stage_fractions"]["stage3"]
    assert noisy["mean_return"] < clean["mean_return"]


@pytest.mark.parametrize("noise", [-0.1, float("nan")])
def test_bad_action_noise_is_rejected(noise):
    with pytest.raises(ValueError, match="action_noise must be a finite std >= 0"):
        solve("laptop", object_names=["laptop_11cbb00f39"], progress=False, action_noise=noise)


def test_noise_on_one_part_of_the_action_leaves_the_other_part_exact():
    """``rollout.Noisy(part=...)``: ``arm`` perturbs only the 6-D palm twist, ``hand`` only the 16 joint targets, each
    with the very draws ``all`` puts there (same generator seed); an unknown part names the valid ones."""
    from dexart_lite.rollout import Noisy

    action = np.linspace(-0.5, 0.5, 22)
    executed = {part: Noisy(lambda obs: action, 0.1, np.random.default_rng(3), part)({})
                for part in ("all", "arm", "hand")}
    assert np.array_equal(executed["arm"][6:], action[6:]) and np.array_equal(executed["hand"][:6], action[:6])
    assert np.all(executed["arm"][:6] != action[:6]) and np.all(executed["hand"][6:] != action[6:])
    assert np.array_equal(executed["arm"][:6], executed["all"][:6])
    assert np.array_equal(executed["hand"][6:], executed["all"][6:])
    with pytest.raises(ValueError, match="unknown noise part 'fingers'; valid choices: all, arm, hand"):
        Noisy(lambda obs: action, 0.1, np.random.default_rng(3), "fingers")


# ----------------------------------------------------------------------------- the imitable lid expert
def test_pursue_on_an_l_shaped_path():
    """Pure pursuit, checked by hand on the path (0,0,0) -> (1,0,0) -> (1,1,0): a point beside the
    first leg aims 0.3 m further along it; near the corner the carrot turns onto the second leg; past
    the end it stops at the end."""
    import numpy as np

    from dexart_lite.experts.geometry import pursue

    path = [np.zeros(3), np.array([1.0, 0, 0]), np.array([1.0, 1, 0])]
    goal, segment = pursue(path, np.array([0.2, -0.5, 0.0]), 0.3)
    np.testing.assert_allclose(goal, [0.5, 0, 0], atol=1e-12)
    assert segment == 0
    goal, segment = pursue(path, np.array([0.9, -0.1, 0.0]), 0.3)
    np.testing.assert_allclose(goal, [1.0, 0.2, 0], atol=1e-12)
    assert segment == 1
    goal, segment = pursue(path, np.array([1.0, 3.0, 0.0]), 0.3)
    np.testing.assert_allclose(goal, [1.0, 1.0, 0], atol=1e-12)


def test_laptop_expert_is_memoryless():
    """The laptop expert is a function of the current state only (what a student can copy): midway
    through an episode, a fresh expert that never saw the episode gives the same action as the one
    that drove it, in every region of its law (approach, lift, wrap, ride)."""
    import numpy as np

    from dexart_lite.experts import FeedbackLidSolver

    env = make("laptop", object_names=["laptop_11cbb00f39"], num_points=32)
    try:
        policy = ScriptedPolicy(env)
        obs, _ = env.reset(seed=0, options={"object": "laptop_11cbb00f39"})
        regions, done, t = set(), False, 0
        while not done:
            action = policy(obs)
            assert isinstance(policy.solver, FeedbackLidSolver)
            if t % 4 == 0 or policy.solver.region not in regions:  # a fresh expert reads the object's URDF: not every step
                regions.add(policy.solver.region)
                fresh = FeedbackLidSolver(env.unwrapped).act(env.unwrapped.state)
                np.testing.assert_allclose(np.clip(fresh, -1, 1), action, atol=1e-5)  # reset-pose rounding
            obs, _, terminated, truncated, info = env.step(action)
            done, t = terminated or truncated, t + 1
        assert info["success"]
        assert {"approach", "lift", "wrap", "ride"} <= regions, regions
    finally:
        env.close()


def test_exploration_noise_benchmark_smoke(tmp_path, monkeypatch, load_benchmark):
    """benchmarks/experts/exploration_noise.py in fast mode: one row per split and noise level, with the
    settings it ran; noise-free, the expert solves its first object."""
    import json

    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("exploration_noise")
    out = bench.main(["--task", "faucet", "--splits", "seen", "unseen", "--json", str(tmp_path / "n.json")])
    rows = json.loads((tmp_path / "n.json").read_text())["rows"]
    assert [(r["split"], r["action_noise"]) for r in rows] == [("seen", 0.0), ("seen", 1.0), ("unseen", 0.0),
                                                               ("unseen", 1.0)]
    assert out["splits"] == ["seen", "unseen"] and (tmp_path / "n.png").is_file()
    assert rows[0]["success_rate"] == 1.0


def test_exploration_noise_benchmark_averages_its_seeds(monkeypatch, load_benchmark):
    """With several seeds, one row per split, noise level and seed, and their mean and std per split and
    noise level: the mean is over the seeds' own rows."""
    import numpy as np

    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("exploration_noise")
    out = bench.main(["--task", "faucet", "--splits", "seen", "--seeds", "0", "1"])
    assert [(r["action_noise"], r["seed"]) for r in out["rows"]] == [(0.0, 0), (0.0, 1), (1.0, 0), (1.0, 1)]
    assert [(m["action_noise"], m["seeds"]) for m in out["mean_over_seeds"]] == [(0.0, [0, 1]), (1.0, [0, 1])]
    for m, pair in zip(out["mean_over_seeds"], (out["rows"][:2], out["rows"][2:])):
        rates = [r["success_rate"] for r in pair]
        assert m["success_rate"] == np.mean(rates) and m["success_std"] == np.std(rates)
    rows = [{"split": "seen", "action_noise": 0.3, "seed": s, "success_rate": rate, "mean_max_stage": 2.0 + s,
             "mean_return": 10.0 * s} for s, rate in ((0, 0.5), (1, 1.0))]
    (m,) = bench.mean_over_seeds(rows)
    assert (m["success_rate"], m["success_std"], m["mean_max_stage"], m["mean_return"]) == (0.75, 0.25, 2.5, 5.0)


def test_synergy_expert_benchmark_runs_the_projected_expert_and_never_compares_a_smoke_run(
        tmp_path, monkeypatch, load_benchmark):
    """benchmarks/experts/synergy_expert.py in fast mode: one row per task and split from a hand="synergy" env (whose
    action check refuses a 22-D action); a smoke run is not set beside the committed full-hand success; a second call
    keeps the rows it did not run."""
    import json

    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("synergy_expert")
    bench.main(["--tasks", "laptop", "--splits", "seen", "--json", str(tmp_path / "s.json")])
    rows = json.loads((tmp_path / "s.json").read_text())["rows"]
    assert [(r["task"], r["split"]) for r in rows] == [("laptop", "seen")]
    assert rows[0]["synergy_success"] == 1.0 and rows[0]["full_hand_success"] is None
    # one task measured again: the other rows of the same file are kept, in the tasks' order
    bench.main(["--tasks", "faucet", "--splits", "seen", "--json", str(tmp_path / "s.json")])
    rows = json.loads((tmp_path / "s.json").read_text())["rows"]
    assert [(r["task"], r["split"]) for r in rows] == [("faucet", "seen"), ("laptop", "seen")]
    assert "command" in rows[1] and "command" not in rows[0]
    with pytest.raises(ValueError, match="at seed 0, not 1 at 5: run every task or pass --json elsewhere"):
        bench.main(["--tasks", "faucet", "--splits", "seen", "--seed", "5", "--json", str(tmp_path / "s.json")])


# ----------------------------------------------------------------------------- physics settings
def test_the_physics_benchmark_keeps_the_control_step_and_compares_every_setting(tmp_path, monkeypatch,
                                                                                 load_benchmark):
    """benchmarks/perf/bench_physics.py: a setting ITERATIONSxFRAME_SKIP reaches the env with the control step
    kept at 40 ms; the report has a speed and a solver row per setting, the baseline's own differences
    being exactly 1x and 0 (fast mode: 5 steps per episode, a smoke run, not evidence)."""
    from dexart_lite.envs.base import physics_setting

    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_physics")
    for bad in ("20", "0x10", "ax10", "20x0", "20x"):
        with pytest.raises(ValueError, match="ITERATIONSxFRAME_SKIP"):
            physics_setting(bad)
    env = make("laptop", num_points=32, **physics_setting("20x5")).unwrapped
    assert env.frame_skip == 5 and env.sim.dt == pytest.approx(0.008) and env.control_dt == pytest.approx(0.04)
    env.close()
    report = bench.main(["--tasks", "laptop", "--settings", "50x10", "20x5", "--json", str(tmp_path / "p.json")])
    speed = report["speed"]["laptop"]
    assert set(speed) == {"50x10", "20x5"} and speed["50x10"]["vs_baseline"] == 1.0
    assert speed["20x5"]["vs_baseline"] == pytest.approx(speed["20x5"]["steps_per_s"] / speed["50x10"]["steps_per_s"])
    for split in ("seen", "unseen"):
        row = report["solvers"]["laptop"][split]
        assert row["50x10"]["minus_baseline"] == 0.0 and row["50x10"]["within_tolerance"]
        assert row["20x5"]["minus_baseline"] == pytest.approx(row["20x5"]["success_rate"] - row["50x10"]["success_rate"])
    assert report["solvers_within_tolerance"]["50x10"] and report["solvers_no_lower_per_task"]["50x10"]["laptop"]
    assert (tmp_path / "p.json").is_file()


def test_bucket_failure_classes_read_the_bail_angle(load_benchmark):
    """benchmarks/experts/bucket_expert_failures.py: a failed episode is 'flung over' in the phase where q first
    passed +0.6 rad, 'fell back' where it sank under -1.3 rad after rising past -1.0, else 'other'
    in its last phase."""
    classify = load_benchmark("bucket_expert_failures").classify
    flung = [("hook", -1.57, 0.0), ("raise", -0.5, 0.0), ("slide", 0.7, 0.0), ("fist", 1.57, 0.0)]
    assert classify(flung) == {"failure": "flung over", "phase": "slide"}
    fell = [("hook", -1.57, 0.0), ("raise", -0.9, 0.0), ("slide", -1.2, 0.0), ("fist", -1.4, 0.0)]
    assert classify(fell) == {"failure": "fell back", "phase": "fist"}
    # sinking under -1.3 before ever rising past -1.0 is not a fall; nor is any angle under +0.6
    low = [("lower", -1.57, 0.0), ("hook", -1.2, 0.0), ("raise", -1.4, 0.0), ("raise", 0.5, 0.0)]
    assert classify(low) == {"failure": "other", "phase": "raise"}


def test_bucket_failure_regrasps_and_lift_swing_read_the_phase_trace(load_benchmark):
    """bucket_expert_failures.py: a regrasp is each entry into ``approach`` from another phase, and the lift's
    swing is the range of q over the first run of ``lift`` steps only."""
    bench = load_benchmark("bucket_expert_failures")
    phases = ["approach", "descend", "close", "approach", "descend", "close", "raise", "lift", "lift", "approach"]
    assert bench.regrasps_from(phases) == ["close", "lift"]
    trace = [("raise", -0.9, 0.0), ("lift", -0.5, 0.0), ("lift", 0.3, 0.0), ("lift", -0.2, 0.0),
             ("approach", 1.5, 0.0), ("lift", -1.5, 0.0)]
    assert bench.lift_swing(trace) == pytest.approx(0.8)
    assert bench.lift_swing([("raise", -0.9, 0.0)]) is None


def test_bucket_failure_benchmark_replays_the_noise_curve_episodes(monkeypatch, load_benchmark):
    """In fast mode (one episode of the first seen bucket) the success equals ``solve``'s at the same
    noise and seed: the same resets and noise draws as benchmarks/experts/exploration_noise.py."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    out = load_benchmark("bucket_expert_failures").main(["--sigma", "0.05", "--splits", "seen"])
    seen = out["splits"]["seen"]
    name = seen["per_episode"][0]["object"]
    expected = solve("bucket", "seen", 1, 0, object_names=[name], progress=False, action_noise=0.05)
    assert seen["episodes"] == 1 and seen["success_rate"] == expected["success_rate"]
    assert sum(seen["failures"].values()) == round(1 - seen["success_rate"])


def test_stage_timeline_orders_the_experts_stages_and_counts_steps_as_the_episode_does(monkeypatch, load_benchmark):
    """benchmarks/experts/stage_timeline.py: on a 40-step laptop episode (fast mode) the expert reaches stage 2
    within it, each stage's first step is after the one before, and none is past the episode's end."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("stage_timeline")
    assert bench.first([1, 1, 2, 3, 2], 2) == 3 and bench.first([1, 1, 2, 3, 2], 3) == 4
    assert bench.first([1, 2], 3) is None
    out = bench.main(["--task", "laptop"])
    episode, = out["episodes"]
    assert episode["steps"] == 40 and episode["first_stage2"] is not None
    reached = [episode[k] for k in bench.KEYS if episode[k] is not None]
    assert reached == sorted(reached) and reached[-1] <= episode["steps"]
    assert out["summary"]["first_stage2"] == {"reached": 1, "of": 1, "min": episode["first_stage2"],
                                              "median": float(episode["first_stage2"]), "max": episode["first_stage2"]}


def test_solve_names_the_noise_parts_on_a_wrong_one():
    """solve(noise_part=...): an unknown part is an error naming the valid ones, raised before any env is built."""
    with pytest.raises(ValueError, match="noise part.*all.*arm.*hand"):
        solve("bucket", "seen", 1, 0, object_names=["bucket_222c59ab44"], progress=False, action_noise=0.1,
              noise_part="wrist")
