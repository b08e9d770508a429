"""Contracts every task env must keep: spaces, reward = sum of named terms, seeding, bad input."""

import importlib
import json
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import dexart_lite
from dexart_lite import objects
from dexart_lite.envs import make

SMALL = dict(num_points=64)  # a small cloud keeps these tests fast


@pytest.fixture(scope="module", params=dexart_lite.TASKS)
def env(request):
    env = make(request.param, **SMALL)
    yield env
    env.close()
    env.close()  # closing twice is safe


def random_actions(n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, size=(n, 22)) * np.r_[[0.3] * 6, [1.0] * 16]


def test_ids_are_registered():
    assert dexart_lite.ENV_IDS == [f"DexArtLite/{t}-v0" for t in ("Faucet", "Bucket", "Laptop", "Toilet")]
    for env_id in dexart_lite.ENV_IDS:
        assert gym.spec(env_id).max_episode_steps == 250


def test_spaces_and_observation(env):
    obs, info = env.reset(seed=0)
    task = env.unwrapped.CATEGORY
    n = 64 + 96
    assert obs["point_cloud"].shape == (n, 3) and obs["point_cloud"].dtype == np.float32
    assert obs["imagined_mask"].shape == (n,) and obs["imagined_mask"][64:].all() and not obs["imagined_mask"][:64].any()
    assert obs["state"].shape == ((33,) if task == "bucket" else (32,))
    assert env.observation_space.contains(obs)
    assert info["point_labels"].shape == (n,) and set(np.unique(info["point_labels"])) <= {0, 1, 2, 3}
    assert info["stage"] in (1, 2, 3) and info["object_name"] in env.unwrapped.objects.names
    assert obs["state"][-1] == 0.0  # t / horizon at the start


def test_reward_is_the_sum_of_its_named_terms(env):
    env.reset(seed=1)
    for action in random_actions(15):
        obs, reward, terminated, truncated, info = env.step(action)
        assert reward == pytest.approx(sum(info["reward_terms"].values()), abs=1e-12)
        assert np.isfinite(reward) and all(np.isfinite(obs[k]).all() for k in ("point_cloud", "state"))
        assert set(info) >= {"stage", "success", "progress", "object_name", "reward_terms", "sim_unstable"}


def test_reward_terms_are_documented_in_the_task_docstring(env):
    env.reset(seed=2)
    _, _, _, _, info = env.step(np.zeros(22))
    doc = type(env.unwrapped).__module__
    import importlib

    text = importlib.import_module(doc).__doc__
    for term in info["reward_terms"]:
        assert term in text, f"reward term {term!r} is not documented in {doc}"


def rollout(env, seed, steps=5):
    obs, info = env.reset(seed=seed)
    out = [obs["point_cloud"].copy(), info["object_name"]]
    for action in random_actions(steps, seed=3):
        obs, reward, *_ = env.step(action)
        out += [obs["point_cloud"].copy(), obs["state"].copy(), reward]
    return out


def test_same_seed_replays_identically_and_different_seeds_differ(env):
    """A fresh env replays a seed bit for bit."""
    task = env.unwrapped.CATEGORY
    fresh, twin = make(task, **SMALL), make(task, **SMALL)
    a, b, c = rollout(fresh, 7), rollout(twin, 7), rollout(fresh, 8)
    fresh.close(), twin.close()
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert not all(np.array_equal(x, y) for x, y in zip(a, c) if not isinstance(x, str))
    first, _ = env.reset(seed=11)
    again, _ = env.reset(seed=11)
    np.testing.assert_array_equal(first["point_cloud"], again["point_cloud"])


@pytest.mark.parametrize("task", ["faucet", "bucket", "laptop", "toilet"])
def test_a_seed_replays_in_the_same_env_after_a_long_episode(task):
    """Resets leave nothing of the previous episode behind: 50 steps of the same seed match bit for
    bit after an 80-step episode in between."""
    env = make(task, **SMALL)
    first = rollout(env, 7, steps=50)
    rollout(env, 3, steps=80)
    again = rollout(env, 7, steps=50)
    env.close()
    for x, y in zip(first, again):
        np.testing.assert_array_equal(x, y)


def episode_after_another_object(task, steps_before):
    """(states of seed 123's first 30 steps in a fresh env, the same after an episode of
    ``steps_before`` steps on another object)."""
    fresh = make(task, **SMALL)
    target = fresh.reset(seed=123)[1]["object_name"]
    other = next(n for n in fresh.unwrapped.objects.names if n != target)
    actions = random_actions(30, seed=3)
    expected = [fresh.step(a)[0]["state"].copy() for a in actions]
    fresh.close()
    env = make(task, **SMALL)
    env.reset(seed=0, options={"object": other})
    for action in random_actions(steps_before, seed=4):
        env.step(0.3 * action)
    assert env.reset(seed=123)[1]["object_name"] == target
    got = [env.step(a)[0]["state"].copy() for a in actions]
    env.close()
    return expected, got


@pytest.mark.parametrize("task", ["faucet", "bucket", "laptop", "toilet"])
def test_an_episode_does_not_depend_on_the_previous_episodes_object(task):
    """The same seed after a 50-step episode on another object = the same seed in a fresh env
    (evaluations visit the objects in turn)."""
    for x, y in zip(*episode_after_another_object(task, steps_before=50)):
        np.testing.assert_array_equal(x, y)


def test_a_faucet_episode_after_a_reset_on_another_faucet_replays():
    """The case that exposed Bullet state outside saveState: 0.034 rad apart in the first step while
    inactive objects were parked next to the world instead of removed."""
    for x, y in zip(*episode_after_another_object("faucet", steps_before=0)):
        np.testing.assert_array_equal(x, y)


def test_bad_actions_raise_and_do_not_break_the_env(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(21))
    with pytest.raises(ValueError, match="non-finite"):
        env.step(np.r_[np.zeros(21), np.nan])
    obs, reward, *_ = env.step(np.full(22, 5.0))  # out of range: clipped, not an error
    assert np.isfinite(reward)


def test_the_synergy_hand_is_the_joint_hand_driven_by_the_synergy_targets():
    """hand="synergy": a 9-D action (twist + 3 synergies) that runs exactly as the 22-D action with the
    synergies' joint targets; the wrong action length is refused naming the hand mode."""
    from dexart_lite.robot import synergy_targets

    synergy, joints = make("faucet", hand="synergy", **SMALL), make("faucet", **SMALL)
    assert synergy.action_space.shape == (9,) and joints.action_space.shape == (22,)
    synergy.reset(seed=3), joints.reset(seed=3)
    with pytest.raises(ValueError, match=r"shape \(9,\) \(hand='synergy'\)"):
        synergy.step(np.zeros(22))
    robot = joints.unwrapped.robot
    rng = np.random.default_rng(0)
    for _ in range(8):
        a = rng.uniform(-1, 1, 9) * np.r_[[0.3] * 6, [1.0] * 3]
        full = np.concatenate([a[:6], robot.hand_action(synergy_targets(a[6:]))])
        obs_s, r_s, *_ = synergy.step(a)
        obs_j, r_j, *_ = joints.step(full)
        np.testing.assert_array_equal(obs_s["state"], obs_j["state"])
        assert r_s == r_j
    with pytest.raises(ValueError, match="valid choices: joints, synergy"):
        make("faucet", hand="gripper")
    synergy.close(), joints.close()


def test_the_laptop_expert_projected_on_the_synergies_still_opens_a_laptop():
    """The 3 synergies can express a lid grasp: the scripted expert's hand targets, projected on them
    (``SynergyScriptedPolicy``), open a seen laptop (benchmarks/experts/synergy_expert.py measures all tasks)."""
    from dexart_lite.experts import SynergyScriptedPolicy

    env = make("laptop", num_points=32, hand="synergy")
    expert = SynergyScriptedPolicy(env)
    obs, _ = env.reset(seed=0)
    success = False
    for _ in range(250):
        obs, _, terminated, truncated, info = env.step(expert(obs))
        success |= info["success"]
        if terminated or truncated:
            break
    assert success
    env.close()


def test_unknown_names_raise_listing_the_choices():
    with pytest.raises(ValueError, match="valid choices: faucet, bucket, laptop, toilet"):
        make("fridge")
    with pytest.raises(ValueError, match="seen_half"):
        make("laptop", split="train")
    with pytest.raises(ValueError, match="valid keywords"):
        make("laptop", nmu_points=10)
    with pytest.raises(ValueError):
        make("laptop", object_names=["no_such_laptop"])
    env = make("laptop", object_names=[objects.list_objects("laptop", "seen")[0].name], **SMALL)
    with pytest.raises(ValueError, match="valid choices"):
        env.reset(options={"object": "nope"})
    env.close()


def test_the_world_holds_one_object_and_a_rebuilt_world_replays_the_same_episode():
    """Between episodes the object leaves the world; every REBUILD_EVERY resets the simulation is built
    anew (PyBullet keeps the shapes of removed bodies until then) and the next episode is unchanged."""
    env = make("laptop", split="seen", **SMALL)
    u = env.unwrapped
    bodies = u.sim.c.getNumBodies()  # scenery + robot: no object before the first reset
    names = set()
    for seed in range(12):
        names.add(env.reset(seed=seed)[1]["object_name"])
        assert u.sim.c.getNumBodies() == bodies + 1
    assert len(names) > 3
    expected = rollout(env, 7, steps=10)
    u.REBUILD_EVERY = 1  # the next reset builds a new simulation
    sim = u.sim
    got = rollout(env, 7, steps=10)
    assert u.sim is not sim and sim.client is None  # the old one was closed
    env.close()
    for x, y in zip(expected, got):
        np.testing.assert_array_equal(x, y)


def test_the_undrawn_arm_links_and_scenery_change_no_cropped_point(env):
    """The depth camera skips the arm's base and first link and the scenery, which never reach the crop
    box or the space between it and the camera: drawing them changes the frame, not the cropped cloud."""
    from dexart_lite.experts import ScriptedPolicy

    u = env.unwrapped
    assert [link for link, _ in u._undrawn_links] == [u.robot.body.link("link_base"), u.robot.body.link("link1")]
    obs, _ = env.reset(seed=3)
    expert, frames_differ = ScriptedPolicy(env), False
    for t in range(60):
        obs, *_ = env.step(expert(obs))
        if t % 15 != 14:
            continue
        skipped_frame, skipped = u.sensor.camera.render_depth(), u.sensor.visible_points()
        u._show_undrawn_links(True)
        u._show_scenery(True)
        try:
            drawn_frame, drawn = u.sensor.camera.render_depth(), u.sensor.visible_points()
        finally:
            u._show_undrawn_links(False)
            u._show_scenery(u._draw_scenery)
        frames_differ |= not np.array_equal(skipped_frame[1], drawn_frame[1])  # the base is in view
        for x, y in zip(skipped, drawn):
            np.testing.assert_array_equal(x, y)
    assert frames_differ
    anywhere = make(u.CATEGORY, view_range=(60, 20), **SMALL)  # eyes all around: every link may matter
    assert anywhere.unwrapped._undrawn_links == []
    anywhere.close()


def test_render_returns_an_rgb_image():
    env = make("laptop", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8 and frame.std() > 5
    u = env.unwrapped
    u._show_undrawn_links(True)  # the viewer draws what the depth camera skips
    np.testing.assert_array_equal(env.render(), frame)
    env.close()


@pytest.mark.parametrize("steps", [7, 8])
def test_a_recorded_episode_is_the_rollout_layers_episode_with_a_frame_every_two_steps(steps):
    from dexart_lite.render import record_episode
    from dexart_lite.rollout import run_episodes

    policy = lambda obs: np.r_[[0.2, 0.0, -0.2, 0.0, 0.0, 0.0], np.zeros(16)]  # noqa: E731
    env = make("laptop", render_mode="rgb_array", max_episode_steps=steps, **SMALL)
    frames, summary = record_episode(env, policy, seed=3, every=2)
    episode = run_episodes(policy, env, [(3, None)])[0]
    env.close()
    assert len(frames) == 5  # t = 0, 2, 4, 6 and the last step (7 or 8)
    assert frames[0].size == (320, 240)
    assert summary == {"return": episode["return"], "success": episode["success"], "steps": steps,
                       "object_name": episode["object"]}


@pytest.mark.parametrize("env_id", ["DexArtLite/Faucet-v0", "DexArtLite/Bucket-v0", "DexArtLite/Laptop-v0",
                                    "DexArtLite/Toilet-v0"])
@pytest.mark.filterwarnings("ignore:.*Box observation space m")  # the state vector is unbounded on purpose
def test_gymnasium_check_env_passes(env_id):
    """gymnasium's own checker, determinism checks included (reset and step with the same seed)."""
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, num_points=64)
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


def test_same_seed_gives_the_same_episode_in_two_fresh_processes():
    """Nothing in an episode depends on the process (hash seeds, import order, memory addresses)."""
    import os
    import subprocess
    import sys

    script = ("import hashlib, numpy as np, dexart_lite\n"
              "from dexart_lite.envs import make\n"
              "h = hashlib.sha256()\n"
              "for task in dexart_lite.TASKS:\n"
              "    env = make(task, num_points=64)\n"
              "    obs, _ = env.reset(seed=5)\n"
              "    rng = np.random.default_rng(0)\n"
              "    for _ in range(10):\n"
              "        obs, reward, *_ = env.step(rng.uniform(-0.3, 0.3, 22))\n"
              "        h.update(obs['point_cloud'].tobytes() + obs['state'].tobytes() + np.float64(reward).tobytes())\n"
              "print(h.hexdigest())\n")
    runs = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONHASHSEED": str(seed)}).stdout.strip() for seed in (1, 2)]
    assert len(runs[0]) == 64 and runs[0] == runs[1]


def test_shaped_reward_adds_named_stage2_terms_to_dexarts():
    """reward="shaped": DexArt's terms unchanged (same seed, same actions, same physics) plus three
    stage-2 terms computed from the state by hand; the reward is still the sum of the terms."""
    from dexart_lite.experts import ScriptedPolicy

    envs = {mode: make("laptop", object_names=["laptop_11cbb00f39"], num_points=32, reward=mode, max_episode_steps=120)
            for mode in ("dexart", "shaped")}
    obs = {m: e.reset(seed=0)[0] for m, e in envs.items()}
    expert = ScriptedPolicy(envs["shaped"])
    stage2 = 0
    for _ in range(120):
        action = expert(obs["shaped"])
        out = {m: e.step(action) for m, e in envs.items()}
        obs = {m: o[0] for m, o in out.items()}
        plain, shaped = out["dexart"][4]["reward_terms"], out["shaped"][4]["reward_terms"]
        assert set(shaped) - set(plain) == {"shape_touch", "shape_reach", "shape_progress"}
        assert all(shaped[k] == plain[k] for k in plain)
        assert out["shaped"][1] == pytest.approx(sum(shaped.values()))
        s, info = envs["shaped"].unwrapped._state, out["shaped"][4]
        if info["stage"] == 2:
            stage2 += 1
            assert shaped["shape_touch"] == pytest.approx(0.05 * s.part_contact.sum())
            assert shaped["shape_reach"] == pytest.approx(-0.1 * min(s.dist, 0.5))
            assert shaped["shape_progress"] == pytest.approx(0.5 * max(info["progress"], 0.0))
        else:
            assert shaped["shape_touch"] == shaped["shape_reach"] == shaped["shape_progress"] == 0.0
        if out["shaped"][2] or out["shaped"][3]:
            break
    assert stage2 > 10
    with pytest.raises(ValueError, match="unknown reward 'dense'; valid choices: dexart, shaped, capped, flat"):
        make("laptop", reward="dense")


def test_the_reset_benchmark_times_this_checkout_and_writes_its_report(load_benchmark, tmp_path):
    """Structure only (timings are the benchmark's business): one task, a few resets, no --ref."""
    bench = load_benchmark("bench_reset")
    report = bench.main(["--tasks", "laptop", "--resets", "3", "--rounds", "1", "--json", str(tmp_path / "r.json")])
    row = report["tasks"]["laptop"]
    assert set(row) == {"this_ms_per_reset"} and row["this_ms_per_reset"] > 0
    assert json.loads((tmp_path / "r.json").read_text())["resets"] == 3


def test_the_step_breakdown_times_every_piece_the_step_calls_and_changes_nothing(load_benchmark):
    """bench_sim's breakdown wraps the step's pieces in place: each one must really be called by
    env.step (a renamed or bypassed piece would read 0 ms), the timed step must give the same
    observation as an untimed one, and the wrappers must come off again."""
    bench = load_benchmark("bench_sim")
    action = np.r_[[0.2] * 6, [0.5] * 16]
    plain = make("laptop", point_noise=True, camera_noise=True).unwrapped
    plain.reset(seed=1)
    expected = plain.step(action)[0]
    plain.close()
    env = make("laptop", point_noise=True, camera_noise=True).unwrapped
    env.reset(seed=1)
    timer = bench.PartTimer()
    bench.instrument(env, timer)
    obs = env.step(action)[0]
    assert all(np.array_equal(obs[k], expected[k]) for k in expected)
    assert {name for _, _, name in bench.TIMED_PIECES} == {k for k, v in timer.seconds.items() if v > 0}
    timer.restore()
    assert "step" not in env.sim.__dict__ and "observe" not in env.sensor.__dict__
    assert callable(env.sensor.labels) and not hasattr(env.sensor.labels, "__wrapped__")
    assert type(env.sensor.labels).__name__ == "LabelTable"
    breakdown = bench.step_breakdown("laptop", np.tile(action, (2, 1)), rounds=1)
    assert set(breakdown["ms_per_step"]) == {name for _, _, name in bench.TIMED_PIECES} | {"step_glue", "wrappers"}


def test_the_env_benchmark_compares_with_an_earlier_commit_side_by_side(load_benchmark, tmp_path, git_checkout):
    """Structure only: a few steps of one task, this checkout against a worktree of HEAD (no second
    process: its spawned worker cannot be pickled from a module loaded by path; no memory check)."""
    bench = load_benchmark("bench_envs")
    report = bench.main(["--tasks", "laptop", "--steps", "5", "--rounds", "1", "--resets", "0", "--no-two-process",
                         "--ref", "HEAD",
                         "--json", str(tmp_path / "e.json")])
    row = report["tasks"]["laptop"]
    assert row["steps_per_s"] > 0 and row["ref_steps_per_s"] > 0
    assert row["vs_ref"] == pytest.approx(row["steps_per_s_subprocess"] / row["ref_steps_per_s"])
    assert report["reset_rss_growth_mb"] is None and json.loads((tmp_path / "e.json").read_text())["ref"] == "HEAD"


def test_each_task_spec_is_what_the_env_the_catalog_and_the_experts_use():
    """registration.SPECS: the env classes, the object splits, the experts, the distillation's default mask and
    the state size all follow the one spec of their task."""
    from dexart_lite.experts import SOLVERS
    from dexart_lite.imitation.distill import DROP_STATE
    from dexart_lite.objects import placement
    from dexart_lite.registration import SPECS

    for task, spec in SPECS.items():
        cls = gym.spec(dexart_lite.registration.env_id(task)).entry_point
        module, name = cls.split(":")
        env_cls = getattr(importlib.import_module(module), name)
        assert (env_cls.CATEGORY, env_cls.ROBOT_BASE, env_cls.RAND_POS) == (task, spec.robot_base, spec.rand_pos)
        assert env_cls.RAND_YAW == np.deg2rad(spec.rand_yaw_deg) and placement.RAND_YAW_DEG[task] == spec.rand_yaw_deg
        counts = [len(objects.list_objects(task, split)) for split in ("seen", "unseen", "seen_half")]
        assert counts == [spec.seen, spec.unseen, spec.half], task
        assert SOLVERS[task].__name__ == spec.expert and DROP_STATE.get(task, "") == spec.student_drops
        env = make(task)  # the observation of a student (the state-only diagnostic adds the object's state)
        assert env.observation_space["state"].shape == (spec.state_dim,)
        env.close()


def test_the_state_layouts_are_what_the_env_and_the_experts_emit():
    """registration.STATE_LAYOUT and the privileged layouts, defined once: the state vector's named slices hold
    what the robot reports, the state-only observation and the expert's privileged vector hold the part's
    joint angle and grasp point where the layout says, and a wrong-sized entry is refused by name."""
    from dexart_lite.experts import ScriptedPolicy
    from dexart_lite.registration import (EXPERT_PRIVILEGED, PRIVILEGED_DIM, PRIVILEGED_STATE, SPECS, STATE_ONLY_PRIVILEGED,
                                          privileged_slices, privileged_vector, state_slices)

    assert (PRIVILEGED_STATE, PRIVILEGED_DIM) == (15, 20)
    for task in ("laptop", "bucket"):
        env = make(task, observation="state")
        policy = ScriptedPolicy(env)
        obs, _ = env.reset(seed=0)
        policy(obs)
        s, at = env.unwrapped.state, state_slices(task)
        vector = obs["state"]
        assert at["time"].stop == SPECS[task].state_dim == vector.shape[0] - PRIVILEGED_STATE
        np.testing.assert_allclose(vector[at["qpos"]], s.robot.qpos, atol=1e-6)
        np.testing.assert_allclose(vector[at["palm_pos"]], s.robot.palm_pos, atol=1e-6)
        assert vector[at["time"]] == 0.0 and (at["task"].stop - at["task"].start) == SPECS[task].state_dim - 32
        base = np.asarray(SPECS[task].robot_base)
        extra = vector[SPECS[task].state_dim:]
        for names, v in ((STATE_ONLY_PRIVILEGED, extra), (EXPERT_PRIVILEGED, policy.privileged)):
            p = privileged_slices(names)
            assert v[p["joint"]] == pytest.approx(s.q, abs=1e-5) and v[p["joint_target"]] == pytest.approx(
                s.obj.joint_target, abs=1e-5)
            np.testing.assert_allclose(v[p["grasp_pos"]], s.handle_pos - base, atol=1e-5)
        env.close()
    with pytest.raises(ValueError, match="'joint' has 1 values, got 2"):
        privileged_vector(("joint",), joint=[0.0, 1.0])


def test_no_module_writes_a_task_fact_down_again():
    """The facts of registration.SPECS are assigned nowhere else: a literal robot base, randomisation, split
    size, success threshold, expert table, student mask, state size or state layout elsewhere fails here."""
    names = (r"ROBOT_BASE|RAND_POS|RAND_YAW(_DEG)?|HALF_SIZES|SPLIT_SIZES|SUCCESS_\w+|FAUCET_SUCCESS|BUCKET_LIFT|DROP_STATE"
             r"|SOLVERS|PRIVILEGED_\w+|where")
    literal = r"[-\d(\[\"]|\{\s*\"|np\.deg2rad\(\d"  # a number, tuple, list, string, dict literal or degrees
    repeated = re.compile(rf"^\s*({names})\s*=\s*({literal})|\b3[23] if .*bucket", re.M)
    root = Path(__file__).resolve().parent.parent
    found = [f"{path.relative_to(root)}: {m.group(0).strip()}"
             for folder in ("dexart_lite", "benchmarks") for path in sorted((root / folder).rglob("*.py"))
             if path.name != "registration.py" for m in repeated.finditer(path.read_text())]
    assert not found, found


def test_capped_and_flat_rewards_change_the_bonus_alone():
    """reward="capped": on the faucet the terminal bonus is (horizon - t) * 1.2 * 1.5 rad however far the
    handle turned, where DexArt's pays (horizon - t) * 1.2 * |q|; reward="flat" pays horizon * 1.2 * 1.5 rad
    whatever the step. Every other term is DexArt's, the same seed and actions give the same physics, and the
    reward is still the sum of the terms."""
    from dexart_lite.experts import ScriptedPolicy

    modes = ("dexart", "capped", "flat")
    envs = {mode: make("faucet", object_names=[objects.list_objects("faucet", "seen")[0].name], observation="state",
                       reward=mode) for mode in modes}
    obs = {m: e.reset(seed=0)[0] for m, e in envs.items()}
    expert = ScriptedPolicy(envs["capped"])
    for _ in range(250):
        action = expert(obs["capped"])
        out = {m: e.step(action) for m, e in envs.items()}
        obs = {m: o[0] for m, o in out.items()}
        terms = {m: out[m][4]["reward_terms"] for m in modes}
        for m in modes:
            assert out[m][1] == pytest.approx(sum(terms[m].values()))
            assert all(terms[m][k] == terms["dexart"][k] for k in terms["dexart"] if k != "bonus")
        if out["capped"][2]:
            break
    info, s = out["capped"][4], envs["capped"].unwrapped._state
    assert info["success"] and out["dexart"][2] and out["flat"][2] and info["progress"] > 1.5
    remaining = s.horizon - s.t
    assert 0 < remaining < s.horizon
    assert terms["capped"]["bonus"] == pytest.approx(remaining * 1.2 * 1.5)
    assert terms["flat"]["bonus"] == pytest.approx(s.horizon * 1.2 * 1.5)
    assert terms["dexart"]["bonus"] == pytest.approx(remaining * 1.2 * info["progress"])
    assert terms["dexart"]["bonus"] > terms["capped"]["bonus"]
