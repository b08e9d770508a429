"""Studies (dexart_lite.study): names, resuming, the camera grid, random viewpoints, pretrained students.

The suite runs in fast mode (conftest): a study's runs are distillations of a few dozen frames.
"""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from dexart_lite import cli, study
from dexart_lite.camera import viewpoint
from dexart_lite.envs import make
from dexart_lite.imitation import distill as distill_lib
from dexart_lite.models.pointnet import PointNetEncoder, save_encoder
from tests.processes import kill_once_started
from dexart_lite.rl.checkpoint import actor_critic_from_checkpoint, load_checkpoint

from test_imitation import OBJECT, tiny_distill_config


def test_unknown_study_or_arm_is_a_one_line_error(capsys, tmp_path):
    with pytest.raises(ValueError, match="unknown study 'sizes'; valid choices: objects, encoder"):
        study.run_study("sizes", "laptop", [0], tmp_path)
    with pytest.raises(ValueError, match="unknown arm of the encoder study 'huge'; valid choices: small, medium, large"):
        study.run_study("encoder", "laptop", [0], tmp_path, arms=["huge"])
    assert cli.main(["study", "objects", "--arms", "all", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "valid choices: seen_half, seen" in err


def test_objects_arms_share_the_data_budget(tmp_path):
    half = study.arm_config(study.STUDIES["objects"], "seen_half", "laptop", 0, tmp_path)
    full = study.arm_config(study.STUDIES["objects"], "seen", "laptop", 0, tmp_path)
    n_half, n_full = len(half.object_names()), len(full.object_names())
    assert (n_half, n_full) == (5, 11)
    for field in ("demo_episodes_per_object", "episodes_per_round"):
        ratio = n_half * getattr(half, field) / (n_full * getattr(full, field))
        assert 0.85 <= ratio <= 1.15, (field, ratio)  # the same episodes in total, up to rounding
    assert (half.eval_episodes, half.eval_seed) == (full.eval_episodes, full.eval_seed)
    assert half.out.endswith("seen_half/seed0") and full.out.endswith("seen/seed0")


@pytest.fixture
def distilled(monkeypatch):
    """The configs ``distill`` is called with (it still runs): which runs a study trained, not read back."""
    calls = []
    real = distill_lib.distill

    def counting(cfg):
        calls.append(cfg)
        return real(cfg)

    monkeypatch.setattr(distill_lib, "distill", counting)
    return calls


def test_interrupted_study_resumes_without_redoing_an_arm(tmp_path, distilled):
    overrides = {"objects": OBJECT, "max_episode_steps": 6}
    study.run_study("encoder", "laptop", [0], tmp_path, arms=["small"], overrides=overrides, progress=False)
    assert [(c.encoder, c.seed) for c in distilled] == [("small", 0)]
    first = (tmp_path / "small" / "seed0" / study.RESULT).stat().st_mtime_ns
    result = study.run_study("encoder", "laptop", [0], tmp_path, arms=["small", "medium"], overrides=overrides,
                             progress=False)
    # the finished arm was read back, not run again
    assert [(c.encoder, c.seed) for c in distilled] == [("small", 0), ("medium", 0)]
    assert (tmp_path / "small" / "seed0" / study.RESULT).stat().st_mtime_ns == first
    assert [r["resumed"] for a in ("small", "medium") for r in result["arms"][a]["per_seed"]] == [True, False]
    saved = json.loads((tmp_path / "study.json").read_text())
    assert set(saved["arms"]) == {"small", "medium"}
    assert saved["arms"]["medium"]["parameters"] > saved["arms"]["small"]["parameters"]
    for key in ("seen_success", "unseen_success", "seen_success_std", "wall_time_s", "per_seed"):
        assert key in saved["arms"]["small"]
    assert (tmp_path / "study.png").stat().st_size > 0
    assert "| small |" in (tmp_path / "study.md").read_text()
    # other settings in a finished folder are refused, not silently mixed
    with pytest.raises(ValueError, match="holds a run with other settings"):
        study.run_study("encoder", "laptop", [0], tmp_path, arms=["small"], overrides={**overrides, "lr": 5e-4},
                        progress=False)


def test_run_arm_continues_a_distillation_interrupted_after_a_round(tmp_path, distilled, monkeypatch):
    """A multi-seed script's distillation cut off in DAgger round 2 continues from round 1 (``resume``), it is
    not cleared and trained again; one cut off before any round ended starts again."""
    from dexart_lite.imitation import distill as distill_module

    cfg = tiny_distill_config(tmp_path / "a", max_episode_steps=6)
    real, calls = distill_module.collect_dagger, []

    def interrupted_in_round_2(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(distill_module, "collect_dagger", interrupted_in_round_2)
    with pytest.raises(KeyboardInterrupt):
        study.run_arm(cfg)
    assert (Path(cfg.out) / "rounds" / "1").is_dir() and not (Path(cfg.out) / "rounds" / "2").exists()
    result = study.run_arm(cfg)
    assert [c.resume for c in distilled] == [False, True] and len(calls) == 3  # round 1 was not collected again
    assert [h["round"] for h in result["history"]] == [0, 1, 2] and result["resumed"] is False
    assert not (Path(cfg.out) / "rounds").exists()
    empty = tiny_distill_config(tmp_path / "b", max_episode_steps=6)
    Path(empty.out, "demos").mkdir(parents=True)  # cut off while collecting its demonstrations
    study.run_arm(empty)
    assert distilled[-1].resume is False


def test_parallel_jobs_give_the_runs_of_one_after_the_other(tmp_path):
    """``jobs=2``: the runs go to 2 worker processes (costliest first) and give what ``jobs=1`` gives
    (fast mode: one torch thread either way, and a seed replays bit for bit in any process)."""
    overrides = {"objects": OBJECT, "max_episode_steps": 6}
    kwargs = dict(arms=["small", "medium"], overrides=overrides, progress=False)
    # under two parents: a study does not reuse the runs of one beside it here
    parallel = study.run_study("encoder", "laptop", [1], tmp_path / "a" / "encoder", jobs=2, **kwargs)
    serial = study.run_study("encoder", "laptop", [1], tmp_path / "b" / "encoder", **kwargs)
    keys = ("seed", "seen_success", "unseen_success", "expert_frames", "student_frames", "per_object", "resumed")
    for arm in ("small", "medium"):
        assert [{k: r[k] for k in keys} for r in parallel["arms"][arm]["per_seed"]] == \
               [{k: r[k] for k in keys} for r in serial["arms"][arm]["per_seed"]]
        assert [r["resumed"] for r in parallel["arms"][arm]["per_seed"]] == [False]
    assert (parallel["jobs"], serial["jobs"]) == (2, 1)
    assert "2 runs at a time" in parallel["wall_time_note"]
    # the costliest first: the PointNet's multiply-adds per point order the queue
    costs = {size: study._training_cost(distill_lib.DistillConfig(encoder=size))
             for size in ("small", "medium", "large", "depth_cnn")}
    assert costs["large"] > costs["medium"] > costs["small"] > costs["depth_cnn"] == 0
    assert costs["small"] == 3 * 64 + 64 * 256
    with pytest.raises(ValueError, match="jobs must be >= 1, got 0"):
        study.run_study("encoder", "laptop", [0], tmp_path / "none", jobs=0, **kwargs)


def test_an_arm_identical_to_another_studys_finished_arm_is_reused_not_retrained(tmp_path, distilled):
    overrides = {"objects": OBJECT, "max_episode_steps": 6}
    first = study.run_study("encoder", "laptop", [0], tmp_path / "encoder", arms=["small"], overrides=overrides,
                            progress=False)
    # the imagination study's "with" arm has the encoder study's "small" settings: copied, not trained again
    second = study.run_study("imagination", "laptop", [0], tmp_path / "imagination", overrides=overrides,
                             progress=False)
    assert [(c.encoder, c.imagination) for c in distilled] == [("small", True), ("small", False)]
    reused = second["arms"]["with"]["per_seed"][0]
    assert reused["reused_from"] == str(tmp_path / "encoder" / "small" / "seed0")
    assert reused["seen_success"] == first["arms"]["small"]["seen_success"]
    assert "reused_from" not in second["arms"]["without"]["per_seed"][0]
    copied = json.loads((tmp_path / "imagination" / "with" / "seed0" / study.RESULT).read_text())
    assert copied["config"]["out"] == str(tmp_path / "imagination" / "with" / "seed0")
    assert (tmp_path / "imagination" / "with" / "seed0" / "checkpoint.pt").exists()


def test_a_study_finished_arm_by_arm_keeps_the_earlier_arms(tmp_path, distilled, capsys):
    overrides = {"objects": OBJECT, "max_episode_steps": 6}
    out = tmp_path / "encoder"  # nothing beside it to reuse a run from
    first = study.run_study("encoder", "laptop", [0], out, arms=["small"], overrides=overrides, progress=False)
    # the earlier file holds a "large" arm measured elsewhere (its run folders are gone, e.g. a committed study.json)
    large = {**first["arms"]["small"], "seen_success": 0.25, "parameters": 1}
    large.pop("measured_by")
    earlier = {**first, "arms": {"large": large}, "command": "dexart-lite study encoder --arms large",
               "machine": {"cpu": "another CPU"}}
    assert len(distilled) == 1
    (out / "study.json").write_text(json.dumps(earlier))
    result = study.run_study("encoder", "laptop", [0], out, arms=["small"], overrides=overrides, progress=False)
    assert len(distilled) == 1  # small was read back, large was not trained
    assert list(result["arms"]) == ["small", "large"]  # the study's order
    assert result["arms"]["large"]["seen_success"] == 0.25
    assert result["arms"]["large"]["measured_by"] == {"command": "dexart-lite study encoder --arms large",
                                                      "machine": {"cpu": "another CPU"}}
    assert result["arms"]["small"]["measured_by"]["machine"]["cpu"] != "another CPU"
    assert result["arms"]["small"]["per_seed"][0]["machine"] == result["arms"]["small"]["measured_by"]["machine"]
    assert "Arms measured on different machines" in (out / "study.md").read_text()
    # an earlier file with other seeds is not mixed in, and the run says so
    (out / "study.json").write_text(json.dumps({**earlier, "seeds": [0, 1]}))
    result = study.run_study("encoder", "laptop", [0], out, arms=["small"], overrides=overrides, progress=False)
    assert list(result["arms"]) == ["small"]
    assert "large with other seeds" in capsys.readouterr().out


def test_camera_grid_puts_the_camera_where_the_angles_say():
    grid = study.camera_grid("laptop")
    assert len(grid) == 35 and len({(a, p) for a, p, _ in grid}) == 35
    centre = np.array([0.0, 0.0, 0.5])  # the laptop camera looks from (0, 1, 0.5) at (0, 0, 0.5)
    for d_azimuth, d_polar, pose in grid:
        theta, phi = np.deg2rad(90 + d_azimuth), np.deg2rad(90 + d_polar)
        expected = centre + np.array([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)])
        np.testing.assert_allclose(pose.position, expected, atol=1e-9)
        forward = pose.matrix[:, 2]
        np.testing.assert_allclose(forward, (centre - expected) / np.linalg.norm(centre - expected), atol=1e-9)
    # (0, 0) is the training camera itself
    nominal = next(pose for a, p, pose in grid if (a, p) == (0, 0))
    np.testing.assert_allclose(nominal.matrix, study.nominal_camera("laptop").matrix, atol=1e-9)
    # +polar lowers the camera, +azimuth swings it toward the robot (-x)
    low = viewpoint(study.nominal_camera("laptop"), 0.0, np.deg2rad(20))
    side = viewpoint(study.nominal_camera("laptop"), np.deg2rad(60), 0.0)
    assert low.position[2] < 0.5 and side.position[0] < -0.8


def test_random_viewpoints_stay_on_the_sphere_within_the_range():
    env = make("laptop", split="seen", object_names=[OBJECT], num_points=32, view_range=(60, 20)).unwrapped
    nominal = env.CAMERA
    centre = np.asarray(nominal.position) + nominal.matrix[:, 2]
    positions = []
    for seed in range(6):
        env.reset(seed=seed)
        pose = env.sensor.camera.pose
        offset = np.asarray(pose.position) - centre
        assert np.linalg.norm(offset) == pytest.approx(1.0, abs=1e-9)
        polar, azimuth = np.degrees(np.arccos(offset[2])), np.degrees(np.arctan2(offset[1], offset[0]))
        assert 70 - 1e-6 <= polar <= 110 + 1e-6 and 30 - 1e-6 <= azimuth <= 150 + 1e-6
        positions.append(pose.position)
    assert len({tuple(np.round(p, 6)) for p in positions}) == 6  # a new viewpoint at every reset
    env.close()
    fixed = make("laptop", split="seen", object_names=[OBJECT], num_points=32).unwrapped
    fixed.reset(seed=0)
    assert fixed.sensor.camera.pose == nominal  # no range, no camera noise: DexArt's camera
    fixed.close()
    with pytest.raises(ValueError, match="view_range must be"):
        make("laptop", view_range=(60,))


def test_viewpoint_evaluation_fills_the_grid(tmp_path, monkeypatch):
    cfg = tiny_distill_config(tmp_path, method="bc")
    distill_lib.distill(cfg)
    few = [(a, p, pose) for a, p, pose in study.camera_grid("laptop") if (a, p) in ((0, 0), (60, -20))]
    monkeypatch.setattr(study, "camera_grid", lambda task: few)
    result = study.evaluate_viewpoints(cfg, 1, splits=("seen",), workers=2)
    grid = np.array(result["success"]["seen"])
    assert grid.shape == (5, 7) and np.isfinite(grid).all()
    # a cell computed in a worker process is the one computed here, in this process
    a, p, pose = few[1]
    here = study._evaluate_camera(str(tmp_path / "run" / "checkpoint.pt"), "laptop", "seen", 1, cfg.eval_seed,
                                  {**cfg.env_kwargs(), "camera": pose})
    assert grid[study.VIEW_POLARS.index(p), study.VIEW_AZIMUTHS.index(a)] == here
    assert json.loads((tmp_path / "run" / study.VIEWPOINTS).read_text())["success"] == result["success"]


def test_student_starts_from_a_pretrained_encoder_strictly(tmp_path):
    encoder = PointNetEncoder("small")
    path = save_encoder(encoder, tmp_path / "encoder.pt")
    cfg = tiny_distill_config(tmp_path, method="bc", pretrained=str(path), normalize_points=False, epochs=1)
    distill_lib.validate(cfg)
    result = distill_lib.distill(cfg)
    student = actor_critic_from_checkpoint(load_checkpoint(result["checkpoint"]), result["checkpoint"])
    trunk = student.module[0].module
    assert float(trunk.point_scale) == 1.0 and not trunk.point_loc.any()  # raw metres, as the encoder learnt
    with pytest.raises(ValueError, match="holds a 'medium' PointNetEncoder but the model has a 'small' one"):
        distill_lib.distill(tiny_distill_config(tmp_path, out=str(tmp_path / "other"), method="bc",
                                                pretrained=str(save_encoder(PointNetEncoder("medium"),
                                                                            tmp_path / "medium.pt"))))
    with pytest.raises(FileNotFoundError, match="pretrained encoder not found"):
        distill_lib.validate(tiny_distill_config(tmp_path, pretrained=str(tmp_path / "missing.pt")))


def test_viewpoint_and_imagination_settings_reach_the_envs(tmp_path):
    cfg = tiny_distill_config(tmp_path, rounds=1, imagination=False, view_range="60,20")
    result = distill_lib.distill(cfg)
    manifest = json.loads((tmp_path / "run" / "demos" / "manifest.json").read_text())
    assert manifest["imagination"] is False and manifest["view_range"] == [60.0, 20.0]
    assert manifest["cloud_points"] == 32  # no imagined points
    payload = load_checkpoint(result["checkpoint"])
    assert payload["dims"]["num_points"] == 32
    with pytest.raises(ValueError, match="view_range must be two degrees"):
        distill_lib.validate(tiny_distill_config(tmp_path, view_range="60"))


def test_depth_image_student_the_2d_baseline(tmp_path):
    """encoder=depth_cnn: the env observes the depth image of the cloud's camera, the demonstrations store
    it, the student reads it (not the cloud), and its checkpoint evaluates and loads strictly."""
    env = make("laptop", split="seen", object_names=[OBJECT], num_points=32, depth_image=True)
    obs, _ = env.reset(seed=0)
    assert obs["depth_image"].shape == (64, 64) and env.observation_space.contains(obs)
    assert (obs["depth_image"] > 0).sum() > 200  # the laptop and the robot
    env.close()
    cfg = tiny_distill_config(tmp_path, encoder="depth_cnn", rounds=1, image_shift=4)  # DrQ shifts in training
    result = distill_lib.distill(cfg)
    assert result["encoder"] is None  # no PointNet to save on its own
    from dexart_lite.demos import load_demos

    demos = load_demos(tmp_path / "run" / "demos")
    assert demos["depth_image"].shape[1:] == (64, 64)
    student = actor_critic_from_checkpoint(load_checkpoint(result["checkpoint"]), result["checkpoint"])
    trunk = student.module[0].module
    assert type(trunk.encoder).__name__ == "DepthCNN" and student.module[0].in_keys[0] == "depth_image"
    assert 0.0 <= result["seen_success"] <= 1.0
    with pytest.raises(ValueError, match="no PointNet"):
        distill_lib.validate(tiny_distill_config(tmp_path, encoder="depth_cnn", pretrained=str(tmp_path / "x.pt")))
    with pytest.raises(ValueError, match="valid choices: small, medium, large, depth_cnn"):
        distill_lib.validate(tiny_distill_config(tmp_path, encoder="resnet"))


def test_pretrain_study_prepares_encoders_and_loads_them(tmp_path):
    """The pretrain study pretrains one encoder per method (fast mode: tiny datasets, one epoch), reports
    their metrics, and each arm's student starts from its method's encoder, loaded strictly."""
    metrics = study.prepare_pretrained("laptop", tmp_path, progress=False)
    assert set(metrics) == {"seg", "cls", "recon", "simsiam"}
    assert 0.0 <= metrics["seg"]["val"]["miou"] <= 1.0 and metrics["cls"]["data"].startswith("objects-only")
    for method in metrics:
        cfg = study.arm_config(study.STUDIES["pretrain"], method, "laptop", 0, tmp_path)
        assert cfg.pretrained == str(tmp_path / "pretrained" / method / "encoder.pt") and not cfg.normalize_points
        distill_lib.validate(cfg)  # the file exists
    scratch = study.arm_config(study.STUDIES["pretrain"], "scratch", "laptop", 0, tmp_path)
    assert scratch.pretrained is None and not scratch.normalize_points  # the arms differ in the encoder only
    again = study.prepare_pretrained("laptop", tmp_path, progress=False)  # read back, not redone
    assert again == metrics



@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process tree from /proc (Linux)")
def test_sigterm_stops_a_parallel_study_and_leaves_no_worker_behind(tmp_path):
    """``kill`` (SIGTERM) on ``study --jobs 2`` ends it as Ctrl-C does, with its one-line message, and its
    worker processes, busy in distillations that would train for hours, end with it."""
    import os
    import sys

    env = {k: v for k, v in os.environ.items() if k != "DEXART_LITE_FAST"}  # fast mode would cap the epochs
    busy = ["objects=" + OBJECT, "num_points=32", "max_episode_steps=6", "demo_episodes_per_object=1", "rounds=1",
            "episodes_per_round=1", "epochs=1000000", "eval_episodes=1"]  # a run that trains for hours
    stderr = tmp_path / "stderr.txt"
    status = kill_once_started(
        [sys.executable, "-m", "dexart_lite.cli", "study", "encoder", "--task", "laptop", "--seeds", "2", "--arms",
         "small", "--jobs", "2", "--no-progress", "--set", *busy, "--out", str(tmp_path / "study")],
        lambda pid: (tmp_path / "study" / "small" / "seed1").exists(),  # both workers have started a run
        "study workers", stderr, env)
    assert status == 130
    # the one-line message and no traceback; the line order is not checked: multiprocessing's resource
    # tracker may print its own warning about the killed workers' semaphores after it (seen in about 1 run in 3)
    text = stderr.read_text()
    assert "dexart-lite study: interrupted" in text.splitlines() and "Traceback" not in text


def test_a_ppo_run_short_of_its_frames_continues_and_a_finished_one_is_read_back(tmp_path):
    """``run_arm`` is the read-back rule of every multi-seed script, PPO included: a run asked for more frames
    than it has continues from its checkpoint (not from scratch), a finished one is read back, and a folder
    that holds more frames than asked, or other settings, is refused."""
    from test_rl import tiny_config

    cfg = tiny_config(tmp_path, frames=100, frames_per_batch=100, minibatch=50, workers=0)
    first = study.run_arm(cfg)
    assert (first["frames"], first["continued"], first["resumed"]) == (100, False, False)
    assert 0.0 <= first["seen_success"] <= 1.0 and set(first["per_object"]) == {"seen", "unseen"}
    more = study.run_arm(dataclasses.replace(cfg, frames=200))
    assert (more["frames"], more["continued"], more["resumed"]) == (200, True, False)
    assert [row["frames"] for row in more["history"]] == [100, 200]  # the first batch kept, one more trained
    again = study.run_arm(dataclasses.replace(cfg, frames=200, max_minutes=5.0, threads=1))  # how it runs: not compared
    assert again["resumed"] and again["history"] == json.loads(json.dumps(more["history"]))
    with pytest.raises(ValueError, match="more than the 100 asked"):
        study.run_arm(cfg)
    with pytest.raises(ValueError, match="holds a run with other settings"):
        study.run_arm(dataclasses.replace(cfg, frames=200, lr=5e-4))


def test_a_distillation_made_outside_the_runner_is_read_back_not_deleted(tmp_path, distilled):
    """A finished ``distill`` run without ``run.json`` (e.g. made by ``dexart-lite distill``) is adopted by
    ``run_arm`` with its own success and frames; one with other settings is refused, not deleted."""
    cfg = tiny_distill_config(tmp_path, rounds=1, max_episode_steps=6)
    made = distill_lib.distill(cfg)
    assert len(distilled) == 1 and not (Path(cfg.out) / study.RESULT).exists()
    record = study.run_arm(cfg)
    assert len(distilled) == 1 and record["resumed"] and record["adopted"]  # not trained again
    assert (record["seen_success"], record["unseen_success"]) == (made["seen_success"], made["unseen_success"])
    assert record["expert_frames"] + record["student_frames"] == made["expert_frames"] + made["student_frames"]
    (Path(cfg.out) / study.RESULT).unlink()
    with pytest.raises(ValueError, match="holds a run with other settings"):
        study.run_arm(dataclasses.replace(cfg, lr=5e-4))
    assert (Path(cfg.out) / "checkpoint.pt").exists() and len(distilled) == 1
