"""Expert demonstrations, behaviour cloning and DAgger (dexart_lite.imitation) on tiny budgets.

Every env here is the Laptop with 32 observed points, a few steps per episode and one object;
training uses one torch thread (two threads are many times slower on a busy 2-core machine).
"""

import dataclasses
import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from tensordict import TensorDict
from torchrl.envs.utils import ExplorationType, set_exploration_type

from dexart_lite import cli
from dexart_lite import objects as objects_lib
from dexart_lite import experts
from dexart_lite.envs import make
from dexart_lite import demos as demos_lib
from dexart_lite.demos import collect_demos, load_demos
from dexart_lite.imitation.distill import (DistillConfig, collect_dagger, dagger_beta, distill, same_settings,
                                           successful_episodes, train_student,
                                          validate)
from dexart_lite.models.actor_critic import action_log_std, architecture, make_actor_critic, trunk_of
from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint
from dexart_lite.rl.env import torch_threads
from dexart_lite.rollout import per_object_summary, run_episodes
from dexart_lite.utils import parse_overrides

OBJECT = objects_lib.list_objects("laptop", "seen")[0].name
STEPS = 8  # steps per episode
TINY_DEMOS = dict(task="laptop", split="seen", episodes_per_object=2, noise=0.3, num_points=32,
                  max_episode_steps=STEPS, object_names=[OBJECT], progress=False)
TINY_ENV = dict(split="seen", object_names=[OBJECT], num_points=32, point_noise=True, camera_noise=True,
                max_episode_steps=STEPS)


def tiny_distill_config(tmp_path, **overrides) -> DistillConfig:
    return dataclasses.replace(DistillConfig(), **{
        "task": "laptop", "objects": OBJECT, "demo_episodes_per_object": 1, "rounds": 2, "episodes_per_round": 1,
        "epochs": 2, "epochs_per_round": 1, "batch_size": 16, "num_points": 32, "max_episode_steps": STEPS,
        "eval_episodes": 1, "threads": 1, "progress": False, "out": str(tmp_path / "run"), **overrides})


class FakeExpert:
    """A deterministic expert of the observation alone; counts its calls."""

    def __init__(self, env):
        self.calls = 0

    @staticmethod
    def act(state: np.ndarray) -> np.ndarray:
        return np.tanh(3.0 * np.resize(state, 22)).astype(np.float32)

    def __call__(self, obs):
        self.calls += 1
        return self.act(obs["state"])


def stored_bytes(folder) -> dict[str, str]:
    return {f.name: hashlib.sha256(f.read_bytes()).hexdigest() for f in sorted((folder / "samples").glob("*.memmap"))}


@pytest.fixture(scope="module")
def demos_dir(tmp_path_factory):
    """Two noisy expert episodes of one laptop."""
    out = tmp_path_factory.mktemp("demos") / "seed0"
    collect_demos(seed=0, out=out, **TINY_DEMOS)
    return out


# ------------------------------------------------------------------ rollout layer
def test_run_episodes_reports_every_episode_and_resets_the_policy():
    class Policy:
        resets = 0

        def reset(self):
            self.resets += 1

        def __call__(self, obs):
            return np.zeros(22)

    env, policy, steps = make("laptop", **{**TINY_ENV, "max_episode_steps": 5}), Policy(), []
    results = run_episodes(policy, env, [(3, OBJECT), (4, OBJECT)], on_step=lambda *a: steps.append(a[-1]))
    env.close()
    assert policy.resets == 2 and steps == [0, 1, 2, 3, 4] * 2
    assert [(r["object"], r["seed"], r["steps"], len(r["stages"])) for r in results] == [(OBJECT, 3, 5, 5),
                                                                                          (OBJECT, 4, 5, 5)]
    assert all(r["max_stage"] >= max(r["stages"]) and not r["success"] for r in results)
    summary = per_object_summary(results)
    assert summary["success_rate"] == 0.0 and summary["objects"][OBJECT]["episodes"] == 2


# ------------------------------------------------------------------ demonstrations
def test_demos_round_trip_replays_and_labels_are_the_clean_expert_actions(demos_dir):
    manifest, data = json.loads((demos_dir / "manifest.json").read_text()), load_demos(demos_dir)
    assert manifest["samples"] == data.batch_size[0] == 2 * STEPS and manifest["objects"] == [OBJECT]
    assert data["point_cloud"].shape == (2 * STEPS, 32 + 96, 3) and data["point_cloud"].dtype == torch.float32
    assert data["imagined_mask"].dtype == torch.int8 and data["observation"].shape == (2 * STEPS, 32)
    assert data["t"].tolist() == list(range(STEPS)) * 2 and data["episode"].tolist() == [0] * STEPS + [1] * STEPS
    executed, labels = data["action"], data["expert_action"]
    assert executed.abs().max() <= 1.0 and (executed != labels).any(-1).all()  # noise on what ran, not on labels
    # Replay: a fresh env and a fresh expert, the stored executed actions -> the same observations, and
    # the expert, called on each of them, returns exactly the stored label.
    env = make("laptop", **TINY_ENV)
    expert = experts.ScriptedPolicy(env)
    for k, episode in enumerate(manifest["episodes"]):
        obs, _ = env.reset(seed=episode["seed"], options={"object": episode["object"]})
        for t in range(episode["steps"]):
            i = k * STEPS + t
            np.testing.assert_array_equal(obs["point_cloud"], data["point_cloud"][i].numpy())
            np.testing.assert_array_equal(obs["state"], data["observation"][i].numpy())
            np.testing.assert_array_equal(expert(obs).astype(np.float32), labels[i].numpy())
            obs, *_ = env.step(executed[i].numpy())
    env.close()


def test_same_seed_same_bytes_other_seed_other_bytes(demos_dir, tmp_path):
    collect_demos(seed=0, out=tmp_path / "again", **TINY_DEMOS)
    collect_demos(seed=1, out=tmp_path / "other", **TINY_DEMOS)
    reference = stored_bytes(demos_dir)
    assert len(reference) == len(demos_lib.SAMPLE_SPECS)
    assert stored_bytes(tmp_path / "again") == reference
    other = stored_bytes(tmp_path / "other")
    for name in ("point_cloud.memmap", "action.memmap", "expert_action.memmap"):
        assert other[name] != reference[name]


def test_labels_are_the_expert_outputs_with_or_without_noise(tmp_path, monkeypatch):
    monkeypatch.setattr(experts, "ScriptedPolicy", FakeExpert)
    for noise in (0.0, 0.5):
        collect_demos(seed=0, out=tmp_path / str(noise), **{**TINY_DEMOS, "noise": noise})
        data = load_demos(tmp_path / str(noise))
        labels = torch.as_tensor(np.stack([FakeExpert.act(s) for s in data["observation"].numpy()]))
        assert torch.equal(data["expert_action"], labels)
        if noise == 0.0:
            assert torch.equal(data["action"], labels)
        else:
            assert (data["action"] != labels).any(-1).all()


def test_missing_corrupt_or_foreign_demos_give_one_line_errors(demos_dir, tmp_path, capsys):
    def broken(name, edit):
        folder = tmp_path / name
        shutil.copytree(demos_dir, folder)
        edit(folder)
        return folder

    def edit_manifest(**changes):
        def edit(folder):
            manifest = json.loads((folder / "manifest.json").read_text())
            (folder / "manifest.json").write_text(json.dumps({**manifest, **changes}))
        return edit

    samples = "samples"
    cases = {
        tmp_path / "nowhere": (FileNotFoundError, "no demonstrations folder"),
        broken("no_manifest", lambda f: (f / "manifest.json").unlink()): (FileNotFoundError, "has no manifest.json"),
        broken("not_json", lambda f: (f / "manifest.json").write_text("{oops")): (ValueError, "not a readable"),
        broken("foreign", edit_manifest(format="dexart_lite.pretrain.dataset")): (ValueError, "not a dexart_lite demo"),
        broken("future", edit_manifest(format_version=99)): (ValueError, "format version 99"),
        broken("more", edit_manifest(samples=99)): (ValueError, "the manifest implies"),
        broken("no_array", lambda f: (f / samples / "action.memmap").unlink()): (ValueError, "action.memmap is missing"),
        broken("cut", lambda f: (f / samples / "point_cloud.memmap").write_bytes(b"\0" * 100)): (ValueError, "100 bytes"),
        broken("no_meta", lambda f: (f / samples / "meta.json").unlink()): (ValueError, "corrupt demonstrations"),
    }
    for folder, (error, message) in cases.items():
        with pytest.raises(error, match=message) as info:
            load_demos(folder)
        assert len(str(info.value).splitlines()) == 1, str(info.value)
    # through the command line: `distill --demos` on a foreign folder
    assert cli.main(["distill", "--demos", str(tmp_path / "foreign"), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert "not a dexart_lite demonstrations manifest" in err and len(err.splitlines()) == 1


def test_cli_writes_demos(tmp_path, capsys):
    out = tmp_path / "cli_demos"
    assert cli.main(["data", "demos", "--task", "laptop", "--split", "seen", "--episodes-per-object", "1", "--noise",
                     "0.1", "--seed", "3", "--out", str(out), "--num-points", "32", "--max-episode-steps", "4",
                     "--objects", OBJECT, "--no-progress"]) == 0
    assert f"{out}: 4 samples" in capsys.readouterr().out
    manifest = demos_lib.read_manifest(out)
    assert (manifest["seed"], manifest["noise"], manifest["samples"]) == (3, 0.1, 4)
    assert set(manifest["versions"]) >= {"torch", "torchrl", "tensordict", "pybullet"}
    assert load_demos(out).batch_size == (4,)
    assert cli.main(["data", "demos", "--episodes-per-object", "0", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip()
    assert "episodes_per_object must be >= 1" in err and len(err.splitlines()) == 1


# ------------------------------------------------------------------ DAgger and training
def test_dagger_round_follows_the_student_and_labels_with_the_expert():
    constant = np.full(22, 0.3, np.float32)
    env = make("laptop", **TINY_ENV)
    runs = {}
    for beta in (0.0, 1.0, 0.5):
        expert, student_calls = FakeExpert(env), []
        student = lambda obs: student_calls.append(1) or constant  # noqa: E731
        data, results, share = collect_dagger(env, expert, student, [(5, OBJECT), (6, OBJECT)], beta,
                                              np.random.default_rng(0), [OBJECT], first_episode=7)
        labels = torch.as_tensor(np.stack([FakeExpert.act(s) for s in data["observation"].numpy()]))
        assert torch.equal(data["expert_action"], labels) and expert.calls == data.batch_size[0] == 2 * STEPS
        assert data["episode"].unique().tolist() == [7, 8] and [r["steps"] for r in results] == [STEPS, STEPS]
        is_student = (data["action"] == torch.as_tensor(constant)).all(-1)
        is_expert = (data["action"] == labels).all(-1)
        assert (is_student | is_expert).all()
        runs[beta] = data
        if beta == 0.0:
            assert is_student.all() and share == 0.0 and len(student_calls) == 2 * STEPS
        elif beta == 1.0:
            assert is_expert.all() and share == 1.0 and not student_calls
        else:
            assert 0 < is_expert.sum() < 2 * STEPS and share == float(is_expert.float().mean())
    env.close()
    # the env followed the executed actions: same seeds, different trajectories
    assert not torch.equal(runs[0.0]["observation"][1:STEPS], runs[1.0]["observation"][1:STEPS])


def synthetic_samples(n=64, points=40, state_dim=32) -> TensorDict:
    gen = torch.Generator().manual_seed(0)
    state = torch.randn(n, state_dim, generator=gen)
    return TensorDict({"point_cloud": torch.randn(n, points, 3, generator=gen), "observation": state,
                       "expert_action": torch.tanh(state[:, :22])}, [n])


@pytest.mark.parametrize("loss", ["mse", "l1", "nll"])
def test_train_student_fits_the_expert_labels(loss):
    torch.manual_seed(0)
    actor_critic, data = make_actor_critic(32, 22), synthetic_samples()
    log_std = action_log_std(actor_critic).clone()
    with torch_threads(1):
        losses = train_student(actor_critic, data, DistillConfig(batch_size=16, loss=loss, lr=3e-3), epochs=30)
    assert len(losses) == 30
    if loss in ("mse", "l1"):
        assert losses[-1] < 0.5 * losses[0]
        assert torch.equal(action_log_std(actor_critic), log_std)  # MSE and L1 leave the log-std alone
    else:
        assert losses[-1] < losses[0] - 0.5 and not torch.equal(action_log_std(actor_critic), log_std)


def test_l1_follows_the_majority_of_split_labels_where_mse_averages_them():
    """One observation labelled +0.8 in 7 of 10 samples and -0.8 in 3 (an expert's two rules meeting at
    a boundary): MSE's mean action is 0.7 * 0.8 - 0.3 * 0.8 = 0.32, L1's median the majority's 0.8."""
    data = synthetic_samples(n=40)
    data["point_cloud"][:] = data["point_cloud"][0]
    data["observation"][:] = data["observation"][0]
    data["expert_action"] = torch.full((40, 22), 0.8)
    data["expert_action"][torch.arange(40) % 10 < 3] = -0.8
    means = {}
    for loss in ("mse", "l1"):
        torch.manual_seed(0)
        actor_critic = make_actor_critic(32, 22)
        with torch_threads(1):
            train_student(actor_critic, data, DistillConfig(batch_size=40, loss=loss, lr=3e-3, ema=0.0), epochs=150)
            with set_exploration_type(ExplorationType.DETERMINISTIC):
                means[loss] = actor_critic.get_policy_operator()(data[:1].clone())["loc"]
    assert torch.allclose(means["mse"], torch.full_like(means["mse"], 0.32), atol=0.05)
    assert ((means["l1"] > 0.65) & (means["l1"] < 0.9)).all()  # near 0.8, far from the mean 0.32


# ------------------------------------------------------------------ the whole run and its checkpoint
@pytest.fixture(scope="module")
def tiny_run(demos_dir, tmp_path_factory):
    """BC on the two demonstration episodes, then 2 DAgger rounds; the buffer keeps 20 samples."""
    cfg = tiny_distill_config(tmp_path_factory.mktemp("distill"), demos=str(demos_dir), max_samples=20, gif=True)
    return cfg, distill(cfg)


def test_tiny_run_logs_rounds_evaluates_and_reports(tiny_run):
    cfg, result = tiny_run
    history = result["history"]
    assert [(h["round"], h["phase"]) for h in history] == [(0, "bc"), (1, "dagger"), (2, "dagger")]
    assert [h["beta"] for h in history[1:]] == pytest.approx([cfg.beta, cfg.beta * cfg.beta_decay])
    assert [h["buffer"] for h in history] == [16, 20, 20]  # capped: the oldest samples went first
    assert (result["expert_frames"], result["student_frames"]) == (16, 2 * STEPS)
    run_dir = Path(result["checkpoint"]).parent
    lines = (run_dir / "log.csv").read_text().splitlines()
    assert len(lines) == 4 and lines[0].startswith("round,phase,beta")
    for split in ("seen", "unseen"):
        assert json.loads((run_dir / f"eval_{split}.json").read_text())["success_rate"] == result[f"{split}_success"]
    report = (run_dir / "report.md").read_text()
    assert f"| 2 | dagger | {cfg.beta * cfg.beta_decay:.3f} |" in report and "| unseen | **all** |" in report and "rounds.png" in report
    assert (run_dir / "rounds.png").stat().st_size > 0 and (run_dir / "episode.gif").stat().st_size > 0
    assert not (run_dir / "buffer").exists()


def test_student_checkpoint_loads_strictly_and_evaluates_from_the_command_line(tiny_run, tmp_path, capsys):
    cfg, result = tiny_run
    payload = load_checkpoint(result["checkpoint"])
    student = actor_critic_from_checkpoint(payload, result["checkpoint"])  # strict load into make_actor_critic
    fresh = make_actor_critic(payload["dims"]["state_dim"], payload["dims"]["action_dim"], cfg.encoder,
                              **architecture(payload["dims"]))
    assert student.state_dict().keys() == fresh.state_dict().keys()
    assert payload["dims"]["head"] == cfg.head_widths() and payload["dims"]["normalize"] == cfg.normalize
    # DexArt's own architecture (64, 64 head, raw inputs) has other weights: the strict load refuses it
    with pytest.raises(RuntimeError):
        make_actor_critic(payload["dims"]["state_dim"], payload["dims"]["action_dim"], cfg.encoder).load_state_dict(
            payload["model"], strict=True)
    assert payload["frames"] == 32 and payload["batches"] == 3 and len(payload["history"]) == 3
    out = tmp_path / "eval.json"
    assert cli.main(["eval", "--ckpt", result["checkpoint"], "--split", "unseen", "--episodes-per-object", "1",
                     "--json", str(out)]) == 0
    assert "| unseen | **all** |" in capsys.readouterr().out
    assert json.loads(out.read_text())["episodes"] == len(objects_lib.list_objects("laptop", "unseen"))
    with pytest.raises(ValueError, match="already holds a run"):
        distill(cfg)


def test_an_interrupted_distillation_resumes_to_the_uninterrupted_student(tiny_run, tmp_path, monkeypatch):
    """Stopped during DAgger round 2, the run keeps round 1's state; ``--resume`` ends with exactly the weights,
    buffer sizes and frames of the uninterrupted run (same settings), then drops the resume state."""
    from dexart_lite.imitation import distill as distill_module

    cfg = dataclasses.replace(tiny_run[0], out=str(tmp_path / "run"), gif=False)
    real, calls = distill_module.collect_dagger, []

    def interrupted_in_round_2(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt  # the session ends here
        return real(*args, **kwargs)

    monkeypatch.setattr(distill_module, "collect_dagger", interrupted_in_round_2)
    with pytest.raises(KeyboardInterrupt):
        distill(cfg)
    run_dir = Path(cfg.out)
    assert (run_dir / "resume.pt").is_file() and (run_dir / "rounds" / "1").is_dir()
    assert len((run_dir / "log.csv").read_text().splitlines()) == 3  # header, BC, round 1
    with pytest.raises(ValueError, match="already holds a run; pass --resume"):
        distill(cfg)
    with pytest.raises(ValueError, match=r"started with other settings \(lr\)"):
        distill(dataclasses.replace(cfg, resume=True, lr=5e-4))
    monkeypatch.setattr(distill_module, "collect_dagger", real)
    state = torch.load(run_dir / "resume.pt", weights_only=True)  # as if saved before these fields existed:
    del state["config"]["beta_min"], state["config"]["drop_failed"]  # their defaults are what that run had
    torch.save(state, run_dir / "resume.pt")
    # a run killed outright (no clean-up, as a terminated pool worker) leaves its scratch buffer behind
    (run_dir / "buffer").mkdir()
    (run_dir / "buffer" / "point_cloud.memmap").write_bytes(b"stale")
    resumed = distill(dataclasses.replace(cfg, resume=True))
    whole = load_checkpoint(tiny_run[1]["checkpoint"])
    again = load_checkpoint(resumed["checkpoint"])
    assert whole["model"].keys() == again["model"].keys()
    assert all(torch.equal(whole["model"][k], again["model"][k]) for k in whole["model"])
    assert [(h["round"], h["buffer"], h["frames"], h["loss"]) for h in resumed["history"]] == \
        [(h["round"], h["buffer"], h["frames"], h["loss"]) for h in tiny_run[1]["history"]]
    assert not (run_dir / "resume.pt").exists() and not (run_dir / "rounds").exists()
    with pytest.raises(FileNotFoundError, match="no unfinished distillation"):
        distill(dataclasses.replace(cfg, resume=True))
    # stopped in its evaluation, after the last round: resumed, it trains nothing more and evaluates
    cfg = dataclasses.replace(cfg, out=str(tmp_path / "run_eval"))
    real_eval = distill_module.evaluate_splits
    monkeypatch.setattr(distill_module, "evaluate_splits", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt))
    with pytest.raises(KeyboardInterrupt):
        distill(cfg)
    assert (Path(cfg.out) / "resume.pt").is_file() and not (Path(cfg.out) / "eval_seen.json").exists()
    monkeypatch.setattr(distill_module, "evaluate_splits", real_eval)
    monkeypatch.setattr(distill_module, "collect_dagger", interrupted_in_round_2)  # counts any round run again
    finished = distill(dataclasses.replace(cfg, resume=True))
    assert len(calls) == 2 and finished["seen_success"] == tiny_run[1]["seen_success"]
    final = load_checkpoint(finished["checkpoint"])["model"]
    assert all(torch.equal(whole["model"][k], final[k]) for k in whole["model"])


def ppo_from_student(tiny_run, tmp_path, **overrides):
    """A 1-batch (or longer) in-process PPO run started from the tiny student."""
    from dexart_lite.rl import ppo

    cfg = dataclasses.replace(ppo.PPOConfig(), **{
        "task": "laptop", "num_points": 32, "max_episode_steps": 10, "frames": 100, "frames_per_batch": 100,
        "minibatch": 50, "epochs": 2, "workers": 0, "eval_episodes": 0, "progress": False,
        "init_from": tiny_run[1]["checkpoint"], "init_log_std": -1.6, "out": str(tmp_path / "ppo"), **overrides})
    return ppo.train(cfg)


def test_student_starts_ppo_and_the_critic_warmup_freezes_the_actor(tiny_run, tmp_path):
    student = load_checkpoint(tiny_run[1]["checkpoint"])["model"]
    frozen = ppo_from_student(tiny_run, tmp_path / "warm", critic_warmup=1)
    tuned = ppo_from_student(tiny_run, tmp_path / "free", critic_warmup=0)
    assert frozen["history"][0]["critic_warmup"] == 1.0 and tuned["history"][0]["critic_warmup"] == 0.0
    for result in (frozen, tuned):
        payload = load_checkpoint(result["checkpoint"])
        net = actor_critic_from_checkpoint(payload)  # the run keeps the student's architecture
        assert payload["dims"]["head"] == [256, 256] and payload["dims"]["normalize"]
        assert torch.allclose(action_log_std(net), torch.full((22,), -1.6), atol=0.01)  # set, then one batch
    assert torch.equal(action_log_std(actor_critic_from_checkpoint(load_checkpoint(frozen["checkpoint"]))),
                       torch.full((22,), -1.6))  # the warm-up batch leaves it alone
    warm, free = (load_checkpoint(r["checkpoint"])["model"] for r in (frozen, tuned))
    value_keys = [k for k in student if k.startswith("module.2.")]  # the ActorValueOperator's value head
    assert value_keys
    for key, weight in student.items():
        if "state_independent_scale" in key:
            continue
        if key in value_keys:
            assert not torch.equal(warm[key], weight), key  # the critic learned
        else:
            assert torch.equal(warm[key], weight), key  # trunk, normalisation and policy head untouched
    moved = [k for k in student if k not in value_keys and not torch.equal(free[k], student[k])]
    assert any(k.startswith("module.0.") for k in moved) and any(k.startswith("module.1.") for k in moved)


def test_ppo_bc_term_decays_and_bad_init_is_rejected(tiny_run, demos_dir, tmp_path, capsys):
    from dexart_lite.rl import ppo

    result = ppo_from_student(tiny_run, tmp_path / "bc", frames=300, critic_warmup=1, bc_coef=2.0, bc_decay=0.5,
                              bc_demos=str(demos_dir))
    rows = result["history"]
    assert [r["bc_weight"] for r in rows] == [0.0, 2.0, 1.0]  # off in the warm-up, then decaying per batch
    assert rows[0]["loss_bc"] == 0.0 and all(r["loss_bc"] > 0 for r in rows[1:])
    with pytest.raises(ValueError, match="bc_coef > 0 needs --bc-demos"):
        ppo_from_student(tiny_run, tmp_path / "x", bc_coef=1.0)
    with pytest.raises(ValueError, match="is a small laptop network, not small faucet"):
        ppo_from_student(tiny_run, tmp_path / "y", task="faucet")
    assert cli.main(["train", "--init-from", str(tmp_path / "missing.pt"), "--out", str(tmp_path / "z")]) == 2
    err = capsys.readouterr().err.strip()
    assert "checkpoint not found" in err and len(err.splitlines()) == 1


def test_ppo_anchor_is_the_kl_to_the_student(tiny_run, demos_dir, tmp_path):
    """--anchor-coef: the KL to the initial policy is 0 where the policy is the student, matches the
    Gaussian formula by hand for a shifted mean, is logged after the warm-up only, and needs --init-from."""
    from types import SimpleNamespace

    from dexart_lite.rl.anchor import anchor_kl, anchor_weight

    net = actor_critic_from_checkpoint(load_checkpoint(tiny_run[1]["checkpoint"]))
    samples = load_demos(demos_dir)[:8].clone()
    with torch.no_grad():
        out = net.get_policy_operator()(samples.select("point_cloud", "observation").clone())
        samples["anchor_loc"], samples["anchor_scale"] = out["loc"].clone(), out["scale"].clone()
        policy = net.get_policy_operator()
        assert float(anchor_kl(policy, samples)) == pytest.approx(0.0, abs=1e-6)
        samples["anchor_loc"][:, 3] += 0.1  # one action dimension's mean 0.1 away: KL = 0.1^2 / (2 sigma^2)
        sigma = float(out["scale"][0, 3])
        assert float(anchor_kl(policy, samples)) == pytest.approx(0.01 / (2 * sigma ** 2), rel=1e-4)
    rows = ppo_from_student(tiny_run, tmp_path / "anchor", frames=300, critic_warmup=1, anchor_coef=1.0,
                            anchor_decay=0.5)["history"]
    assert rows[0]["kl_init"] == 0.0 and all(r["kl_init"] > 0 for r in rows[1:])
    assert [r["anchor_weight"] for r in rows] == [0.0, 1.0, 0.5]  # none in the warm-up, then x anchor_decay
    with pytest.raises(ValueError, match="anchor_coef > 0 needs --init-from"):
        ppo_from_student(tiny_run, tmp_path / "x", init_from=None, anchor_coef=1.0)
    with pytest.raises(ValueError, match="anchor_decay must be in"):
        ppo_from_student(tiny_run, tmp_path / "y", anchor_coef=1.0, anchor_decay=0.0)
    # a floor stops the decay: 1, 0.5, then held at 0.3 instead of 0.25, 0.125
    floored = SimpleNamespace(anchor_coef=1.0, anchor_decay=0.5, anchor_floor=0.3, critic_warmup=1)
    assert [anchor_weight(floored, b) for b in range(5)] == [0.0, 1.0, 0.5, 0.3, 0.3]
    with pytest.raises(ValueError, match=r"anchor_floor must be in \[0, anchor_coef=1.0\]"):
        ppo_from_student(tiny_run, tmp_path / "z", anchor_coef=1.0, anchor_decay=0.9, anchor_floor=2.0)


def test_bench_finetune_smoke_reads_back_a_finished_seed(tiny_run, tmp_path, monkeypatch, capsys, load_benchmark):
    """The fine-tuning benchmark in fast mode: frame 0 is the student's own success, then PPO's; a second
    call reads the finished seed back instead of training again."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_finetune")
    argv = ["--seeds", "0", "--frames", "200", "--students", str(Path(tiny_run[1]["checkpoint"]).parent),
            "--runs", str(tmp_path), "--json", str(tmp_path / "ft.json")]
    result = bench.main(argv)
    row = result["per_seed"][0]
    assert [h["critic_warmup"] for h in row["history"]] == [1.0, 0.0] and row["frames"] == 200
    for key in ("student_seen", "student_unseen", "seen_success", "unseen_success"):
        assert 0.0 <= result[key] <= 1.0
    assert (tmp_path / "ft.png").stat().st_size > 0
    assert bench.main(argv)["per_seed"][0]["history"] == row["history"]
    # a seed recorded before a PPOConfig field existed (here anchor_coef) had its default: still read back
    record = tmp_path / "finetune_laptop_s0" / "run.json"
    done = json.loads(record.read_text())
    del done["config"]["anchor_coef"]
    record.write_text(json.dumps(done))
    assert bench.main(argv)["per_seed"][0]["history"] == row["history"]
    assert "finished before, read back" in capsys.readouterr().out
    # the held-out evaluation: the student's and the final policy's, cached next to their checkpoints
    held = bench.main([*argv, "--heldout-episodes", "1", "--heldout-seed", "7"])["heldout"]
    cache = tmp_path / "finetune_laptop_s0" / "heldout_unseen_e1_seed7.json"
    assert json.loads(cache.read_text())["success_rate"] == held["per_seed"][0]["unseen_success"]
    assert held["per_seed"][0]["episodes"] == {"seen": len(objects_lib.list_objects("laptop", "seen")),
                                               "unseen": len(objects_lib.list_objects("laptop", "unseen"))}
    assert (Path(row["student"]) / "heldout_seen_e1_seed7.json").exists()


def test_finetune_summary_pools_the_paired_heldout_changes_of_every_variant(tmp_path, load_benchmark):
    """benchmarks/rl/finetune_summary.py: one row per seed of every finetune_<task>*.json with held-out results
    (smoke runs and files without them are left out), the changes averaged by hand."""
    bench = load_benchmark("finetune_summary")

    def write(name, rows, **extra):
        per_seed = [{"seed": r[0], "student": f"s{r[0]}"} for r in rows]
        heldout = {"episodes_per_object": 20, "per_seed": [
            {"seed": r[0], "student_seen": r[1], "seen_success": r[2], "student_unseen": r[3], "unseen_success": r[4]}
            for r in rows]}
        (tmp_path / name).write_text(json.dumps({"frames": 300, "variant": name[:-5], "per_seed": per_seed,
                                                 "heldout": heldout, **extra}))

    write("finetune_faucet.json", [(0, 0.5, 0.7, 0.5, 0.4), (1, 0.6, 0.6, 0.5, 0.6)])
    write("finetune_faucet_x.json", [(0, 0.5, 0.4, 0.5, 0.5)])
    write("finetune_faucet_smoke.json", [(0, 0.0, 1.0, 0.0, 1.0)], fast_mode=True)
    (tmp_path / "finetune_faucet_old.json").write_text(json.dumps({"frames": 300, "per_seed": []}))
    write("finetune_laptop.json", [(0, 0.0, 1.0, 0.0, 1.0)])
    result = bench.main(["--task", "faucet", "--results", str(tmp_path), "--json", str(tmp_path / "sum.json")])
    assert [(r["file"], r["seed"]) for r in result["runs"]] == [
        ("finetune_faucet.json", 0), ("finetune_faucet.json", 1), ("finetune_faucet_x.json", 0)]
    seen, unseen = result["pooled"]["seen"], result["pooled"]["unseen"]
    assert seen["mean_change"] == pytest.approx((0.2 + 0.0 - 0.1) / 3)
    assert (seen["up"], seen["equal"], seen["down"]) == (1, 1, 1)
    assert unseen["mean_change"] == pytest.approx((-0.1 + 0.1 + 0.0) / 3)
    assert unseen["std_change"] == pytest.approx(0.1)  # sample std of (-0.1, 0.1, 0)
    with pytest.raises(SystemExit, match="no finetune_toilet"):
        bench.main(["--task", "toilet", "--results", str(tmp_path)])


def test_dagger_beta_decays_to_its_floor():
    plain = DistillConfig(beta=0.5, beta_decay=0.6)
    assert [dagger_beta(plain, r) for r in (1, 2, 3, 4)] == pytest.approx([0.5, 0.3, 0.18, 0.108])
    floored = dataclasses.replace(plain, beta_min=0.2)
    assert [dagger_beta(floored, r) for r in (1, 2, 3, 4, 10)] == pytest.approx([0.5, 0.3, 0.2, 0.2, 0.2])


def test_successful_episodes_keeps_whole_successful_episodes_only():
    """Episodes 5 and 7 succeed at their last step, episode 6 never: every step of 5 and 7 stays, none of 6."""
    episode = torch.tensor([5, 5, 5, 6, 6, 7, 7])
    success = torch.tensor([False, False, True, False, False, False, True])
    samples = TensorDict({"episode": episode, "success": success, "t": torch.tensor([0, 1, 2, 0, 1, 0, 1])},
                         batch_size=[7])
    kept = successful_episodes(samples)
    assert kept["episode"].tolist() == [5, 5, 5, 7, 7] and kept["t"].tolist() == [0, 1, 2, 0, 1]
    assert successful_episodes(samples[3:5]).batch_size == (0,)


def test_drop_failed_rounds_add_nothing_when_every_episode_fails(demos_dir, tmp_path):
    """8-step laptop episodes never open the lid: with ``drop_failed`` the DAgger rounds' samples stay out of the
    buffer, while their frames are still counted (the student drove them)."""
    cfg = tiny_distill_config(tmp_path, demos=str(demos_dir), drop_failed=True, eval_episodes=0)
    history = distill(cfg)["history"]
    assert [h["buffer"] for h in history] == [16, 16, 16] and [h["new_samples"] for h in history[1:]] == [0, 0]
    assert [h["student_frames"] for h in history] == [0, STEPS, 2 * STEPS]


def test_time_budget_stops_adding_rounds(tmp_path):
    cfg = tiny_distill_config(tmp_path, max_minutes=1e-4, eval_episodes=0)  # collects its own demonstrations
    result = distill(cfg)
    assert [h["phase"] for h in result["history"]] == ["bc"] and result["seen_success"] is None
    assert load_demos(tmp_path / "run" / "demos").batch_size == (STEPS,)


# ------------------------------------------------------------------ bad input
@pytest.mark.parametrize("overrides, message", [
    ({"method": "ppo"}, "unknown method 'ppo'; valid choices: bc, dagger"),
    ({"loss": "huber"}, "valid choices: mse, l1, nll"),
    ({"split": "unseen"}, "valid choices: seen, seen_half"),
    ({"encoder": "huge"}, "valid choices: small, medium, large"),
    ({"beta": 1.5}, r"beta must be in \[0, 1\], got 1.5"),
    ({"beta": -0.1}, r"beta must be in \[0, 1\]"),
    ({"beta_min": 1.5}, r"beta_min must be in \[0, 1\], got 1.5"),
    ({"demo_episodes_per_object": 0}, "demo_episodes_per_object must be >= 1"),
    ({"episodes_per_round": 0}, "episodes_per_round must be >= 1"),
    ({"rounds": -1}, "rounds must be >= 1"),
    ({"epochs": 0}, "epochs must be >= 1"),
    ({"objects": "laptop_nope"}, "valid choices: laptop_"),
])
def test_bad_configs_name_the_valid_choices(tmp_path, overrides, message):
    with pytest.raises(ValueError, match=message):
        validate(tiny_distill_config(tmp_path, **overrides))


def test_a_run_recorded_before_a_field_existed_is_still_the_same_settings():
    """Finished runs are read back by comparing configs; a field added later (here ``imagination``, as
    if the run predated it) at its default matches a record without it, and any real difference does not."""
    cfg = DistillConfig(task="faucet", seed=2)
    recorded = dataclasses.asdict(cfg)
    assert same_settings(recorded, cfg)
    del recorded["imagination"]
    assert same_settings(recorded, cfg)
    assert not same_settings(recorded, dataclasses.replace(cfg, imagination=False))
    assert not same_settings({**recorded, "seed": 3}, cfg)
    assert not same_settings({**recorded, "a_field_we_never_had": 1}, cfg)
    # how a run executed is not what it learned: a run trained on 2 threads is read back by one asking for 1
    assert same_settings({**recorded, "threads": 0, "progress": True}, dataclasses.replace(cfg, threads=1))


def test_a_run_folder_spelled_absolute_or_relative_is_the_same_settings(tmp_path, monkeypatch):
    """A study re-run with --out as an absolute instead of a relative path reads its finished runs back."""
    monkeypatch.chdir(tmp_path)
    cfg = DistillConfig(out="runs/s/small/seed0", pretrained="runs/s/pretrained/seg/encoder.pt")
    recorded = dataclasses.asdict(cfg)
    absolute = dataclasses.replace(cfg, out=str(tmp_path / "runs/s/small/seed0"),
                                   pretrained=str(tmp_path / "runs/s/pretrained/seg/encoder.pt"))
    assert same_settings(recorded, absolute)
    assert not same_settings(recorded, dataclasses.replace(absolute, out=str(tmp_path / "runs/s/large/seed0")))


def test_cli_prints_one_line_errors_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    for flags, message in ((["--method", "ppo"], "valid choices: bc, dagger"), (["--beta", "2"], "[0, 1]"),
                           (["--episodes-per-round", "0"], "episodes_per_round must be >= 1")):
        assert cli.main(["distill", *flags, "--out", str(out)]) == 2
        err = capsys.readouterr().err.strip()
        assert message in err and len(err.splitlines()) == 1 and err.startswith("dexart-lite distill: error:")
    assert not out.exists()


def test_bench_distill_smoke_and_resume(tmp_path, monkeypatch, capsys, load_benchmark):
    """benchmarks/students/bench_distill.py in fast mode writes the documented keys; run again, it reads the
    finished seed back instead of training it again."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_distill")
    argv = ["--task", "laptop", "--seeds", "0", "--runs", str(tmp_path / "runs"), "--json", str(tmp_path / "d.json")]
    first = bench.main(argv)
    for key in ("task", "method", "seeds", "seen_success", "unseen_success", "per_seed", "expert_frames",
                "student_frames", "wall_time_s", "command", "machine"):
        assert key in first, key
    assert (tmp_path / "d.png").is_file()
    capsys.readouterr()
    again = bench.main(argv)
    assert "finished before, read back" in capsys.readouterr().out
    assert again["per_seed"][0]["wall_time_s"] == first["per_seed"][0]["wall_time_s"]


def test_bench_student_training_smoke_trains_the_same_student_in_every_fp32_variant(tmp_path, monkeypatch,
                                                                                    load_benchmark):
    """benchmarks/perf/bench_student_training.py in fast mode: the variants that only move data or skip the
    weight average train exactly the student fp32 trains (same loss), so their timings compare like for like."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_student_training")
    result = bench.main(["--threads", "1", "--json", str(tmp_path / "t.json")])
    assert json.loads((tmp_path / "t.json").read_text())["samples_per_s_best"].keys() == set(bench.VARIANTS)
    assert result["ratio_to_fp32"]["fp32"] == 1.0
    loss = result["loss_last_epoch"]
    assert loss["in_memory"] == loss["fp32"] == loss["no_ema"]
    assert abs(loss["bf16"] - loss["fp32"]) < 0.1 * loss["fp32"]


def test_bench_student_training_compares_encoder_sizes_side_by_side(tmp_path, monkeypatch, load_benchmark):
    """With --encoders, every variant runs once per PointNet size (labels variant/size, ratios to the first)
    and each size really trains its own student (a different network gives a different loss)."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_student_training")
    result = bench.main(["--threads", "1", "--variants", "fp32", "--encoders", "small", "large"])
    assert list(result["samples_per_s_best"]) == ["fp32/small", "fp32/large"]
    assert result["first"] == "fp32/small" and result["ratio_to_first"]["fp32/small"] == 1.0
    assert result["encoders"] == ["small", "large"]
    loss = result["loss_last_epoch"]
    assert loss["fp32/small"] != loss["fp32/large"]


def test_bench_student_training_chunks_change_the_speed_not_the_student(monkeypatch, load_benchmark):
    """With --chunks, every label runs once per pointnet.CHUNK (labels variant/chunkN): chunking splits the
    batch of clouds, not a cloud, so each chunk trains the same student (same loss to float rounding), and
    the module's CHUNK is restored afterwards."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_student_training")
    from dexart_lite.models import pointnet
    before = pointnet.CHUNK
    result = bench.main(["--threads", "1", "--variants", "fp32", "--chunks", "1", "64"])
    assert list(result["samples_per_s_best"]) == ["fp32/chunk1", "fp32/chunk64"] and result["chunks"] == [1, 64]
    loss = result["loss_last_epoch"]
    assert loss["fp32/chunk1"] == pytest.approx(loss["fp32/chunk64"], rel=1e-5)
    assert pointnet.CHUNK == before


def test_perception_probe_smoke(tmp_path, monkeypatch, load_benchmark):
    """benchmarks/students/perception_probe.py in fast mode: the targets are the expert's privileged state of the
    cloud shown, and every variant reports a finite error per group for both splits."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    probe = load_benchmark("perception_probe")
    out = probe.main(["--variants", "dexart", "labels", "--json", str(tmp_path / "p.json")])
    assert (tmp_path / "p.json").is_file() and out["train_samples"] > 0
    for variant in ("dexart", "labels"):
        for split in ("seen", "unseen"):
            errors = out["results"][variant][split]
            assert set(errors) == set(probe.GROUPS) and all(np.isfinite(v) and v >= 0 for v in errors.values())
    # the targets: the lid's joint angle entry is the env's joint angle (0.2 rad at reset, laptop)
    data = probe.collect("laptop", "seen", 1, 0.0, 0, 2)
    assert data["points"].shape[1:] == (608, 3) and data["labels"].shape[1] == 608
    assert data["privileged"].shape[1] == 20 and abs(float(data["privileged"][0, 9]) - 0.2) < 0.05


def test_input_normalisation_is_set_from_data_and_masks_dropped_entries():
    """The trunk's fixed normalisation: states centred and scaled per entry, points by one centre and
    scale; a dropped entry (t / horizon) changes nothing in the output, a kept one does."""
    actor_critic = make_actor_critic(32, 22, normalize=True)
    trunk = trunk_of(actor_critic)
    states, points = torch.randn(64, 32) * 3 + 1, torch.rand(64, 40, 3) * 0.5
    trunk.set_normalization(states, points, drop=[31])
    torch.testing.assert_close(trunk.state_loc, states.mean(0))
    torch.testing.assert_close(trunk.point_loc, points.reshape(-1, 3).mean(0))
    assert trunk.state_mask[31] == 0 and trunk.state_mask[:31].eq(1).all()
    x, changed_time, changed_qpos = states[:4], states[:4].clone(), states[:4].clone()
    changed_time[:, 31] += 5.0
    changed_qpos[:, 0] += 5.0
    with torch.no_grad():
        out = trunk(points[:4], x)
        assert torch.equal(trunk(points[:4], changed_time), out)
        assert not torch.allclose(trunk(points[:4], changed_qpos), out)
    with pytest.raises(ValueError, match="normalize=False"):
        trunk_of(make_actor_critic(32, 22)).set_normalization(states, points)


def test_bad_architecture_settings_are_rejected(tmp_path):
    for bad in ({"head": "64,,x"}, {"arm_weight": 0.0}, {"drop_state": "time", "normalize": False},
                {"drop_state": "clock"}, {"ema": 1.0}, {"ema": -0.1}):
        with pytest.raises(ValueError):
            validate(tiny_distill_config(tmp_path, **bad))


def test_student_failures_smoke(tiny_run, tmp_path, monkeypatch, load_benchmark):
    """benchmarks/students/student_failures.py: every episode lands in exactly one outcome class, the expert's
    disagreement is finite, and noise is applied (sigma 0 and 0.5 act differently)."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    failures = load_benchmark("student_failures")
    cfg, _ = tiny_run
    out = failures.main(["--runs", cfg.out, "--splits", "seen", "--sigmas", "0", "0.5", "--episodes-per-object", "2",
                         "--json", str(tmp_path / "f.json")])
    assert (tmp_path / "f.json").is_file() and len(out["rows"]) == 2
    for row in out["rows"]:
        total = row["success_rate"] + row["no_contact_frac"] + row["touched_frac"] + row["grasped_frac"]
        assert row["episodes"] == 2 and total == pytest.approx(1.0)
        assert np.isfinite(row["arm_error"]) and row["arm_error"] >= 0 and 0 <= row["stalled_frac"] <= 1
        by_region = row["stalled_by_region"]  # fractions of the stalled steps, named by the expert's rules
        assert set(by_region) <= {"approach", "lift", "wrap", "close", "ride"}
        assert sum(by_region.values()) == pytest.approx(1.0) if by_region else row["stalled_frac"] == 0.0
    assert out["rows"][0]["arm_error"] != out["rows"][1]["arm_error"]


def test_bench_distill_variants_are_typed_and_named(tmp_path, monkeypatch, load_benchmark):
    """--set changes DistillConfig fields with their types; it needs --variant, and unknown fields are refused."""
    bench = load_benchmark("bench_distill")
    assert parse_overrides(["drop_state=time,palm_velocity", "rounds=8", "ema=0.99", "normalize=false",
                            "max_episode_steps=50"], DistillConfig) == \
        {"drop_state": "time,palm_velocity", "rounds": 8, "ema": 0.99, "normalize": False, "max_episode_steps": 50}
    with pytest.raises(ValueError, match="unknown DistillConfig field 'nope'; valid choices: task, method"):
        parse_overrides(["nope=1"], DistillConfig)
    with pytest.raises(ValueError, match="FIELD=VALUE"):
        parse_overrides(["rounds"], DistillConfig)
    with pytest.raises(ValueError, match="needs a --variant"):
        bench.main(["--set", "rounds=2", "--runs", str(tmp_path), "--json", str(tmp_path / "x.json")])


def test_auto_drop_state_masks_the_velocity_on_laptop_only():
    """drop_state="auto": laptop students do not see palm velocity (state 22-27) or the time (last entry);
    faucet students see everything (the mask hurt them, see distill.DROP_STATE)."""
    assert DistillConfig(task="laptop").dropped_state(32) == [31, 22, 23, 24, 25, 26, 27]
    assert DistillConfig(task="faucet").dropped_state(32) == []
    assert DistillConfig(task="bucket", drop_state="time").dropped_state(33) == [32]


def test_success_by_template_weights_objects_by_episodes_and_groups_the_held_out_template(tmp_path,
                                                                                          load_benchmark, monkeypatch):
    """benchmarks/students/success_by_template.py: per split and template, a run's success is the episode-weighted
    mean over that template's objects; the unseen template-C objects form their own row."""
    bench = load_benchmark("success_by_template")
    runs = []
    for r, c_success in enumerate((0.0, 1.0)):
        run = tmp_path / f"run{r}"
        run.mkdir()
        for split in ("seen", "unseen"):
            objects = {}
            for i, info in enumerate(objects_lib.list_objects("laptop", split)):
                success = c_success if info.template == "C" else 0.5
                objects[info.name] = {"success_rate": success, "episodes": 1 + i % 2}  # uneven episodes
            (run / f"eval_{split}.json").write_text(json.dumps({"task": "laptop", "objects": objects}))
        runs.append(run)
    result = bench.by_template(runs)
    rows = {(row["split"], row["template"]): row for row in result["rows"]}
    assert set(rows) == {("seen", "A"), ("seen", "B"), ("seen", "all"), ("unseen", "A"), ("unseen", "B"),
                         ("unseen", "C"), ("unseen", "all"), ("unseen", "held_out_bands")}
    # the held-out-band half: the unseen objects of the seen templates, every one at 0.5 here
    bands = [i for i in objects_lib.list_objects("laptop", "unseen") if i.template != "C"]
    assert rows[("unseen", "held_out_bands")]["objects"] == len(bands) == 3
    assert rows[("unseen", "held_out_bands")]["per_run"] == [0.5, 0.5]
    assert rows[("seen", "all")]["per_run"] == [0.5, 0.5] and rows[("seen", "all")]["objects"] == 11
    assert rows[("unseen", "C")]["per_run"] == [0.0, 1.0] and rows[("unseen", "C")]["success"] == 0.5
    assert rows[("seen", "A")]["per_run"] == [0.5, 0.5]
    c_names = [i.name for i in objects_lib.list_objects("laptop", "unseen") if i.template == "C"]
    assert rows[("unseen", "C")]["objects"] == len(c_names)
    assert result["per_object"][c_names[0]]["per_run"] == [0.0, 1.0]
    for run in runs:  # the same evaluations under paired_eval's held-out names, read with --eval
        for split in ("seen", "unseen"):
            (run / f"eval_{split}.json").rename(run / f"heldout_{split}_e10_seed1000.json")
    held_out = bench.by_template(runs, "heldout_{split}_e10_seed1000.json")
    assert held_out["rows"] == result["rows"] and held_out["eval_file"] == "heldout_{split}_e10_seed1000.json"
    with pytest.raises(FileNotFoundError, match="no eval_seen.json"):
        bench.by_template(runs)
    with pytest.raises(ValueError, match="--eval must contain"):
        bench.main(["--runs", str(runs[0]), "--eval", "heldout.json"])
    # --evaluate: the missing held-out files are made first, for every run's checkpoint and split, with the episodes
    # and seed the pattern names (evaluate_many stood in for: it writes this test's figures under the e3 name)
    import dexart_lite.rl.evaluate as evaluate

    asked = []

    def fake_evaluate_many(work, episodes, seed, jobs=1):
        asked.append((sorted((str(c), s) for c, s in work), episodes, seed, jobs))
        for checkpoint, split in work:
            source = Path(checkpoint).parent / f"heldout_{split}_e10_seed1000.json"
            (Path(checkpoint).parent / f"heldout_{split}_e3_seed7.json").write_text(source.read_text())

    monkeypatch.setattr(evaluate, "evaluate_many", fake_evaluate_many)
    made = bench.main(["--runs", *map(str, runs), "--eval", "heldout_{split}_e3_seed7.json", "--evaluate",
                       "--jobs", "4"])
    assert made["rows"] == result["rows"]
    assert asked == [(sorted((str(r / "checkpoint.pt"), s) for r in runs for s in ("seen", "unseen")), 3, 7, 4)]
    with pytest.raises(ValueError, match="--evaluate writes heldout_"):
        bench.main(["--runs", str(runs[0]), "--eval", "eval_{split}.json", "--evaluate"])


def test_erase_ball_removes_the_points_of_one_ball_and_refills_from_the_rest():
    """Two clusters 1 m apart plus imagined points at the origin, radius <= 0.4 m (>= 0.1 m, more than a cluster's
    8.7 cm diagonal): an erased cloud loses (at least) its whole ball, which cannot reach the other cluster, and
    every point it has is one of its own kept observed points;
    imagined points never move; prob 0 is the identity, prob 1 erases every cloud."""
    from dexart_lite.imitation.distill import erase_ball

    gen = torch.Generator().manual_seed(0)
    a = torch.rand(50, 3, generator=gen) * 0.05  # cluster at the origin + [0, 5 cm)
    b = a + torch.tensor([1.0, 0.0, 0.0])  # cluster at x = 1 m
    cloud = torch.cat([a, b, torch.zeros(10, 3)])  # (110, 3): 100 observed, 10 imagined
    imagined = torch.zeros(110, dtype=torch.bool)
    imagined[100:] = True
    points, mask = cloud.expand(32, 110, 3).clone(), imagined.expand(32, 110)
    out = erase_ball(points, mask, 1.0, 0.4, torch.Generator().manual_seed(1))
    assert torch.equal(out[:, 100:], points[:, 100:])  # imagined: untouched
    for cloud_out in out:
        near_a = (cloud_out[:100, 0] < 0.5)
        assert near_a.all() or (~near_a).all()  # one cluster erased whole, refilled
        kept = cloud[:50] if near_a.all() else cloud[50:100]  # from the other
        assert all((kept == p).all(-1).any() for p in cloud_out[:100])
    sides = {bool((cloud_out[:100, 0] < 0.5).all()) for cloud_out in out}
    assert sides == {True, False}  # the ball lands on either cluster
    assert torch.equal(erase_ball(points, mask, 0.0, 0.2, torch.Generator()), points)
    with pytest.raises(ValueError, match="point_erase must be a probability"):
        validate(tiny_distill_config(Path("unused"), point_erase=1.5))
    with pytest.raises(ValueError, match="point_erase_radius must be"):
        validate(tiny_distill_config(Path("unused"), point_erase=0.5, point_erase_radius=0.0))


def test_random_shift_moves_each_image_whole_and_repeats_its_edges():
    """A 6x6 ramp shifted by up to 2 px: every output is the padded image cropped at one offset (so its
    rows and columns are runs of the input's), edge values repeat, and a batch gets several offsets."""
    from dexart_lite.imitation.distill import random_shift

    image = torch.arange(36.0).reshape(6, 6)
    out = random_shift(image.expand(64, 6, 6), 2, torch.Generator().manual_seed(0))
    padded = torch.nn.functional.pad(image[None, None], (2, 2, 2, 2), mode="replicate")[0, 0]
    crops = {(dy, dx): padded[dy:dy + 6, dx:dx + 6] for dy in range(5) for dx in range(5)}
    offsets = [next(k for k, c in crops.items() if torch.equal(c, o)) for o in out]
    assert len(set(offsets)) > 10 and out.shape == (64, 6, 6)
    assert torch.equal(random_shift(image[None], 0, torch.Generator()), image[None])
    with pytest.raises(ValueError, match="image_shift shifts the depth image"):
        validate(tiny_distill_config(Path("unused"), image_shift=4))


def test_tank_mask_keeps_only_body_points_behind_the_hinge_and_above_the_seat(load_benchmark):
    """benchmarks/students/tank_ablation.py: a toilet root at (1, 2, 0) turned 90 deg about z (its +x is world +y),
    hinge at body (0.1, 0, 0.4), lid 2 cm thick. In the body frame a point
    behind the hinge (x = 0.2 > 0.1 + 0.01 + 0.002) and above the seat (z = 0.45 > 0.39) is tank; the same point as
    lid (label 0), in front of the hinge, or below the seat is not."""
    bench = load_benchmark("tank_ablation")
    root, quat = np.array([1.0, 2.0, 0.0]), (0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4))  # yaw +90 deg (x, y, z, w)
    to_world = lambda x, y, z: root + np.array([-y, x, z])  # noqa: E731  body (x, y, z) -> world after the yaw
    hinge = to_world(0.1, 0.0, 0.4)
    points = np.array([to_world(0.2, 0.05, 0.45), to_world(0.2, 0.05, 0.45), to_world(0.05, 0.0, 0.45),
                       to_world(0.2, 0.0, 0.35), to_world(0.111, 0.0, 0.45), to_world(0.113, 0.0, 0.391)])
    object_, part = 1, 0  # pointcloud.LABELS: 0 functional part, 1 the rest of the object
    labels = np.array([object_, part, object_, object_, object_, object_])
    mask = bench.tank_mask(points, labels, root, quat, hinge, lid_t=0.02)
    assert mask.tolist() == [True, False, False, False, False, True]


def test_tank_eraser_drops_tank_points_on_a_seen_toilet_and_none_on_a_tankless_one(load_benchmark):
    """The eraser installed on a real env: a seen (template A) toilet loses over 5 % of its labelled camera points (the
    tank is ~a quarter of them at the reset), a template C (tankless) toilet none."""
    from dexart_lite import objects as objects_lib
    from dexart_lite.envs import make

    bench = load_benchmark("tank_ablation")
    for split, template in (("seen", "A"), ("unseen", "C")):
        env = make("toilet", split=split, num_points=64)
        dropped = bench.erase_tank(env.unwrapped)
        name = next(i.name for i in objects_lib.list_objects("toilet", split) if i.template == template)
        env.reset(seed=0, options={"object": name})
        assert (dropped[-1] > 0.05) == (template == "A"), (template, dropped)
        env.close()



def test_the_tank_eraser_with_a_probability_hides_some_episodes_and_leaves_the_env_rng_alone(load_benchmark):
    """prob 0.5 over 12 resets of a seen toilet: some episodes lose their tank points and some do not, and the env's
    own draws (object pose, camera noise, point sampling) are those of an env without the eraser."""
    from dexart_lite import objects as objects_lib
    from dexart_lite.envs import make

    bench = load_benchmark("tank_ablation")
    name = next(i.name for i in objects_lib.list_objects("toilet", "seen") if i.template == "A")
    plain, erased = make("toilet", split="seen", num_points=64), make("toilet", split="seen", num_points=64)
    dropped = bench.erase_tank(erased.unwrapped, prob=0.5, seed=3)
    hidden = 0
    for seed in range(12):
        before = len(dropped)
        a, _ = plain.reset(seed=seed, options={"object": name})
        b, _ = erased.reset(seed=seed, options={"object": name})
        hidden += len(dropped) > before
        if len(dropped) == before:  # the tank shown: the very same observation
            assert np.array_equal(a["point_cloud"], b["point_cloud"])
        assert np.array_equal(a["state"], b["state"])
    assert 2 <= hidden <= 10, hidden
    plain.close(), erased.close()


def test_distill_without_tank_writes_the_fields_it_documents(tmp_path, load_benchmark):
    """benchmarks/students/distill_without_tank.py in fast mode (conftest): one seed, one object, one round; the
    student's folder is named for the diagnostic, its success per template comes from its own evaluations, and the
    envs were wrapped only while it distilled; a probability outside [0, 1] is refused."""
    import dexart_lite.envs as envs

    bench = load_benchmark("distill_without_tank")
    make = envs.make
    out = bench.main(["--seeds", "0", "--prob", "1.0", "--runs", str(tmp_path / "runs"),
                      "--json", str(tmp_path / "notank.json")])
    assert envs.make is make
    assert json.loads((tmp_path / "notank.json").read_text()) == json.loads(json.dumps(out))
    row, = out["per_seed"]
    assert Path(row["run"]).name == "toilet_cloud_student_notank_s0" and out["prob"] == 1.0
    assert set(row["per_template"]) == {"seen_A", "seen_B", "unseen_A", "unseen_B", "unseen_C", "unseen_held_out_bands"}
    assert {"command", "machine", "eval_episodes_per_object", "seen_success", "unseen_success"} <= out.keys()
    with pytest.raises(ValueError, match="--prob must be a probability"):
        bench.main(["--prob", "1.5"])


@pytest.mark.parametrize("drop_failed", [False, True])
def test_state_student_drop_failed_keeps_only_the_successful_dagger_episodes(drop_failed, monkeypatch, load_benchmark):
    """state_student.py --drop-failed: a DAgger round adds the samples of its successful episodes only (here the first
    of its two 10-step episodes is marked successful); the demonstrations (round 0) are all kept."""
    monkeypatch.setenv("DEXART_LITE_FAST", "1")  # 1 object, 10-step episodes, 1 demonstration, 1 DAgger round
    script = load_benchmark("state_student")
    real = script.run_episodes

    def first_succeeds(*args, **kwargs):
        results = real(*args, **kwargs)
        return [{**r, "success": i == 0} for i, r in enumerate(results)]

    monkeypatch.setattr(script, "run_episodes", first_succeeds)
    result = script.main(["--task", "laptop", "--episodes-per-round", "2", *(["--drop-failed"] if drop_failed else [])])
    demos, dagger = result["history"]
    assert (demos["kept_episodes"], demos["samples"]) == (1, 10)
    assert (dagger["kept_episodes"], dagger["samples"]) == ((1, 20) if drop_failed else (2, 30))
