"""PointNetEncoder (shapes, sizes, invariance, gradients, strict loading) and the actor-critic."""

import math

import pytest
import torch
from tensordict import TensorDict
from torch import nn
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.objectives import ClipPPOLoss

from dexart_lite.models.actor_critic import Acting, action_log_std, encoder_of, make_actor_critic, set_action_log_std
from dexart_lite.models.pointnet import ENCODER_SIZES, PointNetEncoder, load_encoder, save_encoder

SIZES = list(ENCODER_SIZES)


@pytest.mark.parametrize("size, hidden", [("small", 1), ("medium", 3), ("large", 5)])
def test_layer_structure_matches_dexart(size, hidden):
    enc = PointNetEncoder(size)
    linears = [m for m in enc.mlp if isinstance(m, nn.Linear)]
    assert len(linears) == hidden + 1
    assert linears[0].in_features == 3 and linears[-1].out_features == 256 == enc.feature_dim
    assert [m.out_features for m in linears] == list(ENCODER_SIZES[size])
    assert sum(isinstance(m, nn.GELU) for m in enc.mlp) == hidden
    assert not any(isinstance(m, (nn.BatchNorm1d, nn.LayerNorm)) for m in enc.modules())


@pytest.mark.parametrize("size", SIZES)
def test_shapes_for_any_leading_dims(size):
    enc = PointNetEncoder(size)
    assert enc(torch.randn(5, 608, 3)).shape == (5, 256)
    assert enc(torch.randn(2, 3, 100, 3)).shape == (2, 3, 256)
    assert enc(torch.randn(608, 3)).shape == (256,)
    with pytest.raises(ValueError, match=r"\(\.\.\., N, 3\)"):
        enc(torch.randn(4, 608, 6))


def test_extra_point_channels_enter_the_first_layer_and_the_sparse_backward():
    """in_channels > 3 (xyz + per-point features such as segmentation one-hots): the first layer widens,
    a cloud of the wrong width is refused, and the winner-only backward still equals the dense one."""
    torch.manual_seed(2)
    enc = PointNetEncoder("small", in_channels=7)
    assert enc.mlp[0].in_features == 7 and "in_channels=7" in repr(enc)
    with pytest.raises(ValueError, match=r"\(\.\.\., N, 7\)"):
        enc(torch.randn(2, 608, 3))
    points = torch.randn(40, 64, 7, requires_grad=True)
    weight = torch.randn(40, 256)
    dense = enc.mlp(points).max(dim=-2).values
    grads_dense = torch.autograd.grad((dense * weight).sum(), [points, *enc.parameters()])
    grads_fast = torch.autograd.grad((enc(points) * weight).sum(), [points, *enc.parameters()])
    assert all(((a - b).norm() / b.norm()).item() < 1e-4 for a, b in zip(grads_fast, grads_dense))
    # the extra channels matter: flipping a one-hot changes the feature
    flipped = points.detach().clone()
    flipped[:, :, 3:] = flipped[:, :, 3:].flip(-1)
    assert not torch.allclose(enc(points.detach()), enc(flipped), rtol=1e-3, atol=0)


def test_unknown_size_is_a_one_line_error():
    with pytest.raises(ValueError, match="valid choices: small, medium, large"):
        PointNetEncoder("huge")


@pytest.mark.parametrize("size", SIZES)
def test_pooled_feature_is_permutation_invariant(size):
    torch.manual_seed(0)
    enc = PointNetEncoder(size)
    points = torch.randn(4, 608, 3)
    perm = torch.randperm(608)
    feature = enc(points)
    assert torch.allclose(feature, enc(points[:, perm]), rtol=1e-5, atol=1e-7)
    # ... and it does depend on the points
    assert not torch.allclose(feature, enc(points * 1.5), rtol=1e-3, atol=0)


@pytest.mark.parametrize("size", SIZES)
def test_winner_only_backward_equals_the_dense_max_pool(size):
    torch.manual_seed(1)
    enc = PointNetEncoder(size)
    for layer in enc.mlp:  # variance-preserving weights, so channels pick different points
        if isinstance(layer, nn.Linear):
            nn.init.normal_(layer.weight, std=layer.in_features ** -0.5)
            nn.init.normal_(layer.bias, std=0.1)
    points = torch.randn(70, 128, 3, requires_grad=True)  # 70 clouds: more than one chunk
    weight = torch.randn(70, 256)
    dense = enc.mlp(points).max(dim=-2).values
    grads_dense = torch.autograd.grad((dense * weight).sum(), [points, *enc.parameters()])
    rows = []  # points the first layer sees with autograd on: each distinct winner once
    hook = enc.mlp[0].register_forward_hook(lambda m, i, o: rows.append(i[0].shape[0]) if o.requires_grad else None)
    fast = enc(points)
    hook.remove()
    winners = {(b, p) for b, row in enumerate(enc.mlp(points).max(dim=-2).indices.tolist()) for p in row}
    assert rows == [len(winners)] and len(winners) < 70 * 256
    grads_fast = torch.autograd.grad((fast * weight).sum(), [points, *enc.parameters()])

    def rel(a, b):
        return ((a - b).norm() / b.norm()).item()

    assert rel(fast, dense) < 1e-5  # float rounding only (measured ~3e-7)
    assert all(rel(a, b) < 1e-4 for a, b in zip(grads_fast, grads_dense))  # measured <= 3e-6
    with torch.no_grad():
        assert rel(enc(points), dense) < 1e-5


def test_trunc_normal_init():
    torch.manual_seed(0)
    enc = PointNetEncoder("large")
    weights = torch.cat([m.weight.flatten() for m in enc.mlp if isinstance(m, nn.Linear)])
    assert abs(weights.std().item() - 0.02) < 0.001
    assert weights.abs().max() < 2.0  # the (absolute) truncation bounds of trunc_normal_, as timm / DexArt
    assert all(torch.count_nonzero(m.bias) == 0 for m in enc.mlp if isinstance(m, nn.Linear))


def test_save_and_load_round_trip(tmp_path):
    enc = PointNetEncoder("medium")
    path = save_encoder(enc, tmp_path / "enc.pt")
    loaded = load_encoder(path)
    assert loaded.size == "medium"
    for (k, a), (_, b) in zip(enc.state_dict().items(), loaded.state_dict().items()):
        assert torch.equal(a, b), k
    into = PointNetEncoder("medium")
    assert load_encoder(path, into) is into and torch.equal(into.mlp[0].weight, enc.mlp[0].weight)


def test_strict_load_fails_on_a_size_mismatch(tmp_path):
    path = save_encoder(PointNetEncoder("small"), tmp_path / "small.pt")
    with pytest.raises(ValueError, match="holds a 'small' PointNetEncoder but the model has a 'medium' one"):
        load_encoder(path, PointNetEncoder("medium"))


def test_strict_load_fails_on_missing_or_reshaped_weights(tmp_path):
    enc = PointNetEncoder("small")
    path = save_encoder(enc, tmp_path / "enc.pt")
    payload = torch.load(path, weights_only=True)
    del payload["state_dict"]["mlp.2.bias"]
    torch.save(payload, tmp_path / "missing.pt")
    with pytest.raises(ValueError, match=r"missing \['mlp.2.bias'\]"):
        load_encoder(tmp_path / "missing.pt", PointNetEncoder("small"))
    payload = torch.load(path, weights_only=True)
    payload["state_dict"]["mlp.0.weight"] = torch.zeros(64, 4)
    torch.save(payload, tmp_path / "shape.pt")
    with pytest.raises(ValueError, match=r"wrong shape \['mlp.0.weight'\]"):
        load_encoder(tmp_path / "shape.pt")


def test_corrupt_missing_or_foreign_encoder_files_give_one_line_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="encoder file not found"):
        load_encoder(tmp_path / "nope.pt")
    (tmp_path / "bad.pt").write_bytes(b"\x00garbage" * 10)
    with pytest.raises(ValueError, match="not a readable encoder file") as err:
        load_encoder(tmp_path / "bad.pt")
    assert "\n" not in str(err.value)
    torch.save(PointNetEncoder().state_dict(), tmp_path / "raw.pt")  # a bare state_dict, not save_encoder's format
    with pytest.raises(ValueError, match="not an encoder file written by"):
        load_encoder(tmp_path / "raw.pt")


def _obs(batch, state_dim=32, points=608):
    return TensorDict({"point_cloud": torch.randn(batch, points, 3), "observation": torch.randn(batch, state_dim)},
                      [batch])


def test_actor_critic_outputs_and_init():
    torch.manual_seed(0)
    ac = make_actor_critic(33, 22, "small")
    td = ac(_obs(6, 33))
    assert td["hidden"].shape == (6, 320)
    assert td["action"].shape == td["loc"].shape == (6, 22)
    assert td["action_log_prob"].shape == (6,)
    assert td["state_value"].shape == (6, 1)
    assert torch.all(action_log_std(ac) == 0)  # log-std starts at 0 (std 1), as SB3
    # orthogonal init: the rows of the action layer have norm 0.01, of the value layer norm 1
    action_layer = ac.get_policy_head().module[0].module[0][-1]
    value_layer = ac.get_value_head().module[-1]
    assert torch.allclose(action_layer.weight.norm(dim=1), torch.full((22,), 0.01), atol=1e-5)
    assert math.isclose(value_layer.weight.norm().item(), 1.0, rel_tol=1e-5)
    state_layer = ac.module[0].module.state_mlp[0]  # gain sqrt(2): W^T W = 2 I for a (64, 33) orthogonal matrix
    assert torch.allclose(state_layer.weight.T @ state_layer.weight, 2 * torch.eye(33), atol=1e-4)
    assert abs(encoder_of(ac).mlp[2].weight.std().item() - 0.02) < 0.002  # PointNet keeps its own init


def test_deterministic_action_is_the_mean_and_random_action_is_sampled():
    ac = make_actor_critic(32, 22, "small")
    policy = ac.get_policy_operator()
    obs = _obs(3)
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        out = policy(obs.clone())
    assert torch.equal(out["action"], out["loc"])
    out = policy(obs.clone())  # default: sample
    assert not torch.allclose(out["action"], out["loc"])


@pytest.mark.parametrize("encoder, normalize", [("small", True), ("none", False)])
def test_acting_gives_the_actor_critics_numbers_on_its_weights(encoder, normalize):
    """``Acting`` (collectors, evaluation) = ``actor_critic(td)``: the same loc, scale, value and log-prob, the
    same sampled action from the same torch seed, the mean under DETERMINISTIC; a weight change shows."""
    ac = make_actor_critic(32, 22, encoder, normalize=normalize)
    set_action_log_std(ac, -0.7)
    acting, obs = Acting(ac), _obs(5)
    if encoder == "none":
        del obs["point_cloud"]
    with torch.no_grad():
        for mode in (None, ExplorationType.RANDOM, ExplorationType.DETERMINISTIC):
            outs = []
            for module in (ac, acting):
                torch.manual_seed(3)
                with set_exploration_type(mode) if mode else torch.no_grad():
                    outs.append(module(obs.clone()))
            ref, fast = outs
            for key in ("loc", "scale", "action", "action_log_prob", "state_value"):
                assert fast[key].shape == ref[key].shape and torch.allclose(fast[key], ref[key], atol=1e-6), (mode, key)
            assert torch.equal(fast["action"], fast["loc"]) == (mode == ExplorationType.DETERMINISTIC)
        ac.get_value_head().module[-1].bias.add_(1.0)  # shared, not copied
        assert torch.allclose(acting(obs.clone())["state_value"], ref["state_value"] + 1.0, atol=1e-5)


def test_action_std_starts_at_exp_init_log_std():
    """DexArt starts at std 1 (log std 0); ``init_log_std`` lowers it: the sampled actions' spread follows."""
    torch.manual_seed(0)
    obs = _obs(500)  # 500 x 22 samples: the std is within ~1 % of its value
    for init, std in ((0.0, 1.0), (math.log(0.3), 0.3)):
        ac = make_actor_critic(32, 22, "small", init_log_std=init)
        assert torch.allclose(action_log_std(ac), torch.full((22,), init))
        with torch.no_grad():
            out = ac.get_policy_operator()(obs.clone())
        assert (out["action"] - out["loc"]).std().item() == pytest.approx(std, rel=0.04)


def test_loss_with_the_value_head_runs_the_trunk_once():
    ac = make_actor_critic(32, 22, "small")
    calls = []
    ac.module[0].module.register_forward_hook(lambda *a: calls.append(1))
    loss = ClipPPOLoss(actor_network=ac.get_policy_operator(), critic_network=ac.get_value_head(),
                       entropy_coeff=0.0, critic_coeff=0.5, loss_critic_type="l2", normalize_advantage=True)
    batch = _obs(8)
    with torch.no_grad():
        ac.get_policy_operator()(batch)
    batch["advantage"], batch["value_target"] = torch.randn(8, 1), torch.randn(8, 1)
    calls.clear()
    out = loss(batch)
    assert len(calls) == 1
    total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
    total.backward()
    assert torch.isfinite(total)
    assert encoder_of(ac).mlp[0].weight.grad.abs().sum() > 0  # the critic and actor gradients reach the PointNet


def test_pretrained_encoder_loads_strictly_into_the_trunk(tmp_path):
    pretrained = PointNetEncoder("small")
    nn.init.normal_(pretrained.mlp[2].weight)
    path = save_encoder(pretrained, tmp_path / "enc.pt")
    ac = make_actor_critic(32, 22, "small")
    load_encoder(path, encoder_of(ac))
    assert torch.equal(encoder_of(ac).mlp[2].weight, pretrained.mlp[2].weight)
    with pytest.raises(ValueError, match="'small' PointNetEncoder but the model has a 'large' one"):
        load_encoder(path, encoder_of(make_actor_critic(32, 22, "large")))
