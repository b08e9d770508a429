"""Pretraining: datasets (shapes, labels, determinism, corrupt shards), losses, every method's
training step, and the encoder-only weights going strictly into the PPO actor."""

import json

import numpy as np
import pytest
import torch

from dexart_lite import cli
from dexart_lite import pointcloud as pc
from dexart_lite.models.actor_critic import encoder_of, make_actor_critic
from dexart_lite.models.pointnet import PointNetEncoder, load_encoder, save_encoder
from dexart_lite.objects import CATEGORIES, list_objects
from dexart_lite.pretrain import data as datasets
from dexart_lite.pretrain import train as pretrain
from dexart_lite.pretrain.losses import chamfer_distance, chamfer_terms, confusion_matrix, iou_from_confusion

TASK = "laptop"
SAMPLES = 5  # per object: 4 train + 1 val (seen), 5 test (unseen)


def dam_config(out, seed=0) -> datasets.DamConfig:
    names = [o.name for o in list_objects(TASK, "seen")[:2] + list_objects(TASK, "unseen")[:1]]
    return datasets.DamConfig(task=TASK, split="all", samples_per_object=SAMPLES, out=str(out), seed=seed,
                              objects=",".join(names), progress=False)


def objects_config(out) -> datasets.ObjectsConfig:
    names = [list_objects(c, s)[0].name for c in CATEGORIES for s in ("seen", "unseen")]
    return datasets.ObjectsConfig(samples_per_object=6, out=str(out), seed=0, num_points=256, objects=",".join(names),
                                  progress=False)


@pytest.fixture(scope="module", autouse=True)
def _one_thread():
    """Tiny tensors: one torch thread is faster, and much faster on a shared, busy machine."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def dam(tmp_path_factory):
    out = tmp_path_factory.mktemp("dam")
    datasets.generate_dam(dam_config(out))
    return out


@pytest.fixture(scope="module")
def objects_data(tmp_path_factory):
    out = tmp_path_factory.mktemp("objects")
    datasets.generate_objects(objects_config(out))
    return out


# ----------------------------------------------------------------------------- datasets
def test_dam_shapes_labels_and_manifest(dam):
    train, val, test = (datasets.load_part(dam, p) for p in ("train", "val", "test"))
    assert (len(train), len(val), len(test)) == (2 * 4, 2 * 1, 1 * 5)
    for part in (train, val, test):
        assert part.points.shape[1:] == (608, 3) and part.points.dtype == torch.float32
        assert part.labels.shape == part.points.shape[:2]
        assert part.labels.min() >= 0 and part.labels.max() <= 3
        assert (part.labels[:, 512:] == pc.HAND).all()  # the 96 imagined points are hand points
        assert torch.isfinite(part.points).all() and part.points.abs().max() < 2.0  # m, robot-base frame
        assert (part.category == CATEGORIES.index(TASK)).all()
    assert set(train.labels.unique().tolist()) == {0, 1, 2, 3}
    manifest = datasets.read_manifest(dam / "seen")
    assert manifest["kind"] == "dam" and manifest["task"] == TASK and manifest["seed"] == 0
    assert manifest["label_names"] == list(pc.LABELS) and len(manifest["objects"]) == 2
    assert {"dexart_lite", "numpy", "pybullet"} <= set(manifest["versions"])
    assert set(datasets.read_manifest(dam / "unseen")["parts"]) == {"test"}


def test_no_unseen_object_enters_a_pretraining_part_that_trains_or_chooses(dam, objects_data):
    """The parts pretraining fits (train) and chooses on (val) hold seen objects alone; unseen ones are only tested.
    Read from the datasets' manifests, for both kinds of dataset."""
    for root in (dam, objects_data):
        for split, parts in (("seen", {"train", "val"}), ("unseen", {"test"})):
            manifest = datasets.read_manifest(root / split)
            assert set(manifest["parts"]) == parts
            for record in manifest["objects"]:
                assert record["name"] in {o.name for o in list_objects(record["category"], split)}, (root, split, record)


def test_dam_is_deterministic_per_seed(tmp_path):
    def generate(name: str, seed: int) -> datasets.PointCloudSet:
        cfg = datasets.DamConfig(task=TASK, split="seen", samples_per_object=3, out=str(tmp_path / name), seed=seed,
                                 objects=list_objects(TASK, "seen")[0].name, progress=False)
        datasets.generate_dam(cfg)
        return datasets.load_part(tmp_path / name, "train")

    first, again, other = generate("first", 0), generate("again", 0), generate("other", 1)
    assert torch.equal(first.points, again.points) and torch.equal(first.labels, again.labels)
    assert not torch.equal(first.points, other.points)


def test_objects_dataset(objects_data):
    train, test = datasets.load_part(objects_data, "train"), datasets.load_part(objects_data, "test")
    assert train.points.shape[1:] == (256, 3) and len(train) == 4 * 5 and len(test) == 4 * 6
    assert set(train.labels.unique().tolist()) == {0, 1}  # functional part, rest; no robot
    assert train.label_names == datasets.OBJECT_LABELS
    assert set(train.category.tolist()) == set(test.category.tolist()) == {0, 1, 2, 3}
    assert set(test.template.tolist()) <= {0, 1, 2}


def test_dataset_errors_name_the_file(dam, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(dam, copy)
    shard = copy / "seen" / "train-00000.npz"
    shard.write_bytes(shard.read_bytes()[:500])  # truncated
    with pytest.raises(ValueError, match="corrupt shard") as err:
        datasets.load_part(copy, "train")
    assert str(shard) in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(FileNotFoundError, match="no dataset"):
        datasets.load_part(tmp_path / "nothing", "train")
    with pytest.raises(ValueError, match="already holds a dataset"):
        datasets.generate_dam(dam_config(dam))


# ----------------------------------------------------------------------------- losses and metrics
def test_chamfer_matches_brute_force():
    gen = torch.Generator().manual_seed(0)
    a, b = torch.rand(2, 7, 3, generator=gen), torch.rand(2, 5, 3, generator=gen)
    for sqrt in (True, False):
        a_to_b, b_to_a = chamfer_terms(a, b, sqrt=sqrt)
        for i in range(2):
            def nearest(x, y):
                out = []
                for p in x.tolist():
                    d2 = min(sum((pi - qi) ** 2 for pi, qi in zip(p, q)) for q in y.tolist())
                    out.append(d2**0.5 if sqrt else d2)
                return sum(out) / len(out)

            assert a_to_b[i].item() == pytest.approx(nearest(a[i], b[i]), rel=1e-5)
            assert b_to_a[i].item() == pytest.approx(nearest(b[i], a[i]), rel=1e-5)
    assert torch.allclose(chamfer_distance(a, a), torch.zeros(2), atol=1e-5)


def test_iou_from_confusion():
    pred, target = torch.tensor([0, 0, 1, 1, 2]), torch.tensor([0, 1, 1, 1, 0])
    confusion = confusion_matrix(pred, target, 4)
    assert confusion.sum() == 5 and confusion[1, 0] == 1
    iou = iou_from_confusion(confusion)  # class 0: 1 / 3, class 1: 2 / 3, class 2: 0, class 3 absent
    assert iou[:3].tolist() == pytest.approx([1 / 3, 2 / 3, 0.0]) and torch.isnan(iou[3])


def test_simsiam_view_is_a_moved_subset():
    points = torch.rand(3, 50, 3)
    view = pretrain.simsiam_view(points, torch.Generator().manual_seed(0))
    again = pretrain.simsiam_view(points, torch.Generator().manual_seed(0))
    assert view.shape == points.shape and torch.equal(view, again)
    assert (view[..., 2] - points[..., 2]).abs().max() < 1.0  # z only jittered (and points duplicated)
    assert not torch.allclose(view, points, atol=0.05)


# ----------------------------------------------------------------------------- methods
@pytest.mark.parametrize("method", pretrain.METHODS)
def test_every_method_loss_decreases_on_a_fixed_batch(method, dam, objects_data):
    data = datasets.load_part(objects_data if method == "cls" else dam, "train")
    torch.manual_seed(0)
    cfg = pretrain.PretrainConfig(method=method, recon_hidden=64, recon_grid=2, recon_coarse=32)
    encoder, head = PointNetEncoder("small"), pretrain.make_head(cfg, data.num_classes)
    optimizer = torch.optim.Adam([*encoder.parameters(), *head.parameters()], lr=3e-3)
    batch = next(pretrain.batches(data, 8))
    losses = []
    for _ in range(12):
        loss, _ = pretrain.batch_loss(method, encoder, head, batch, generator=torch.Generator().manual_seed(0))
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < losses[0], losses


@pytest.mark.parametrize("method", pretrain.METHODS)
def test_train_writes_encoder_that_loads_strictly_into_the_ppo_actor(method, dam, objects_data, tmp_path):
    data = objects_data if method == "cls" else dam
    cfg = pretrain.PretrainConfig(method=method, data=str(data), out=str(tmp_path / method), epochs=2,
                                  batch_size=4, recon_hidden=64, recon_grid=2, recon_coarse=32, progress=False)
    result = pretrain.train(cfg)
    metrics = json.loads((tmp_path / method / "metrics.json").read_text())
    assert metrics["method"] == method and "test" in metrics and metrics["steps"] == result["history"][-1]["steps"]
    assert pretrain.MAIN_METRIC[method] in metrics["val"]
    assert (tmp_path / method / "curves.png").stat().st_size > 0
    assert (tmp_path / method / "curves.csv").read_text().count("\n") == 1 + len(result["history"])
    actor_critic = make_actor_critic(state_dim=32, action_dim=22, encoder="small")
    encoder = load_encoder(result["encoder"], encoder_of(actor_critic), strict=True)
    trained = torch.load(result["encoder"], weights_only=True)["state_dict"]
    assert all(torch.equal(v, encoder.state_dict()[k]) for k, v in trained.items())
    method_back, head = pretrain.load_head(result["head"])
    assert method_back == method and sum(p.numel() for p in head.parameters()) > 0


def test_mismatched_encoder_files_raise_one_line_errors(dam, tmp_path):
    actor_encoder = encoder_of(make_actor_critic(state_dim=32, action_dim=22, encoder="small"))
    medium = save_encoder(PointNetEncoder("medium"), tmp_path / "medium.pt")
    head = pretrain.save_head(torch.nn.Linear(2, 2), pretrain.PretrainConfig(), 4, tmp_path / "head.pt")
    for path in (medium, head):
        with pytest.raises(ValueError) as err:
            load_encoder(path, actor_encoder, strict=True)
        assert "\n" not in str(err.value)


def test_cli_data_and_pretrain(dam, tmp_path, capsys):
    out = tmp_path / "cli"
    names = ",".join(list_objects(c, "seen")[0].name for c in ("laptop", "faucet"))
    assert cli.main(["data", "objects", "--split", "seen", "--samples-per-object", "3", "--num-points", "64",
                     "--objects", names, "--out", str(out / "data"), "--no-progress"]) == 0
    assert np.load(out / "data" / "seen" / "train-00000.npz")["points"].shape == (4, 64, 3)
    assert cli.main(["pretrain", "--method", "cls", "--data", str(out / "data"), "--out", str(out / "run"),
                     "--epochs", "1", "--batch-size", "2", "--no-progress"]) == 0
    assert (out / "run" / "encoder.pt").is_file()
    capsys.readouterr()
    assert cli.main(["pretrain", "--method", "cls", "--data", str(dam), "--out", str(out / "bad")]) == 2
    assert cli.main(["pretrain", "--method", "nope", "--data", str(dam), "--out", str(out / "bad")]) == 2
    assert cli.main(["pretrain", "--data", str(tmp_path / "missing"), "--out", str(out / "bad")]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 3 and all(line.startswith("dexart-lite pretrain: error:") for line in errors)


def test_bench_pretraining_smoke(tmp_path, monkeypatch, load_benchmark):
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    bench = load_benchmark("bench_pretraining")
    assert bench.main(["--json", str(tmp_path / "bench.json"), "--threads", "1"]) == 0
    results = json.loads((tmp_path / "bench.json").read_text())
    assert set(results["methods"]) == set(pretrain.METHODS) and results["dam"]["laptop"]["ms_per_cloud"] > 0
