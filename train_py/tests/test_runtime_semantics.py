"""What the runtime's choices mean, on packages whose decoder is set by hand:
the AoT head calls moves along +x forward (+1) and along -x backward (-1),
while the distance head rates -x highest. So exploration must move along +x
(rejecting the top-distance candidates, whose AoT is wrong), the goal mode
along -x; `aot_classes` in model.json must be read; and training's class
order (class = AoT + 1) must be the one the runtime reads."""

import json

import numpy as np
import pytest
import torch
import umpnet
from umpnet_train import collect, fixture, train
from umpnet_train.export import export_model

CANONICAL = fixture.CANONICAL
crafted = fixture.steering_model


def package(path, columns=CANONICAL, classes=None):
    model, cfg = crafted(columns)
    export_model(model, cfg, path, {"command": "test_runtime_semantics", "trained": False})
    if classes is not None:
        meta = json.loads((path / "model.json").read_text())
        meta["aot_classes"] = list(classes)
        (path / "model.json").write_text(json.dumps(meta))
    return path


def choose(pkg, mode, n=6):
    policy = umpnet.Policy(str(pkg), seed=3)
    h, w = policy.resolution
    rng = np.random.default_rng(0)
    images = rng.normal(size=(n, h, w, 10)).astype(np.float32)
    pixels = np.array([[h // 2, w // 2]] * n, dtype=np.int64)
    return policy.direction_batch(images, images.copy(), pixels, mode=mode)


def test_exploration_moves_forward_and_the_goal_mode_back(tmp_path):
    pkg = package(tmp_path / "pkg")
    assert json.loads((pkg / "model.json").read_text())["aot_classes"] == [-1, 0, 1]
    for r in choose(pkg, "explore"):
        x = r["direction"][0]
        assert x > 0.1, r["direction"]
        # The candidates with the largest predicted distance lie along -x and
        # were predicted backward: rejected, although they rate highest.
        best = int(np.argmax(r["distance"]))
        assert r["candidates"][best][0] < -0.5 and r["aot"][best] == -1
        chosen = r["candidates"].index(r["direction"])
        assert r["aot"][chosen] == 1 and r["distance"][chosen] < r["distance"][best]
    for r in choose(pkg, "goal"):
        assert r["direction"][0] < -0.9, r["direction"]
        assert r["aot"][r["candidates"].index(r["direction"])] == -1


def test_aot_classes_are_read_and_honoured(tmp_path):
    reference = choose(package(tmp_path / "canonical"), "explore")
    # The same model with its output columns in another order, declared as such: same choices.
    declared = package(tmp_path / "declared", columns=(1, 0, -1), classes=(1, 0, -1))
    assert choose(declared, "explore") == reference
    # Declared wrongly: the runtime believes the columns and walks the other way.
    wrong = package(tmp_path / "wrong", columns=(1, 0, -1), classes=CANONICAL)
    assert all(r["direction"][0] < -0.1 for r in choose(wrong, "explore"))
    for bad in ([1, 1, 0], [-1, 0], [-1, 0, 2]):
        with pytest.raises(ValueError, match="aot_classes"):
            umpnet.Policy(str(package(tmp_path / f"bad{len(bad)}{bad[-1]}", classes=bad)))


def test_training_labels_use_the_class_order_the_runtime_reads():
    model, cfg = crafted()
    x = torch.tensor([[1.0, 0, 0], [-1.0, 0, 0], [0.0, 1, 0]])
    e = torch.zeros(3, cfg.embedding)
    dist, logits = model.decoder(e, e, x)
    # The moves the runtime reads as forward, backward and none, labelled so.
    aot = np.array([1, -1, 0])
    out = {}
    train.direction_losses(cfg, dist, logits, np.zeros(3, np.float32), aot, torch.full((3,), 1 / 3), "", out)
    assert float(out["metric/aot_accuracy"]) == 1.0
    # The opposite labelling disagrees on both moves.
    train.direction_losses(cfg, dist, logits, np.zeros(3, np.float32), -aot, torch.full((3,), 1 / 3), "", out)
    assert float(out["metric/aot_accuracy"]) == pytest.approx(1 / 3)


def test_dynamic_dimensions_are_probed_at_load(tmp_path):
    """An ONNX file may leave the embedding width dynamic; a model.json that
    disagrees with what the network really outputs is a load error naming the
    file and tensor, not a broadcast panic on the first input."""
    import onnx

    pkg = package(tmp_path / "pkg")
    for name in ("direction_encoder.onnx", "direction_decoder.onnx"):
        model = onnx.load(pkg / name)
        for value in [*model.graph.input, *model.graph.output]:
            dims = value.type.tensor_type.shape.dim
            if value.name.endswith("embedding") and len(dims) == 2:
                dims[1].dim_param = "width"  # dynamic: the static check cannot see it
        onnx.save(model, pkg / name)
    assert len(choose(pkg, "explore")) == 6  # still a good package
    meta = json.loads((pkg / "model.json").read_text())
    meta["embedding"] = 2 * meta["embedding"]
    (pkg / "model.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=r"direction_encoder\.onnx.*dist_embedding.*expected \[1, 32\]"):
        umpnet.Policy(str(pkg))


def test_training_explores_with_the_wanted_arrow_of_time():
    # The same hand-set decoder: training's greedy choice must follow `wanted`.
    model, cfg = crafted()
    n = 4
    rng = np.random.default_rng(0)
    obs = {
        "image": rng.normal(size=(n, cfg.height, cfg.width, 10)).astype(np.float32),
        "reference": rng.normal(size=(n, cfg.height, cfg.width, 10)).astype(np.float32),
        "gripper_pixel": np.full((n, 2), 5, np.int64),
    }
    for wanted, sign in ((1, 1.0), (-1, -1.0)):
        dirs, ranked = collect.choose_directions(model, "umpnet", obs, np.full(n, wanted), 0.0, rng)
        assert np.all(sign * dirs[:, 0] > 0.1), (wanted, dirs)
        assert np.all(sign * ranked[:, 0, 0] > 0.1)


def test_the_distance_loss_reaches_the_distance_head():
    model, cfg = crafted()
    x = torch.nn.functional.normalize(torch.randn(6, 3), dim=1)
    e = torch.randn(6, cfg.embedding)
    dist, logits = model.decoder(e, e, x)
    out = {}
    total = train.direction_losses(
        cfg, dist, logits, np.full(6, 0.5, np.float32), np.array([1, -1, 0, 1, -1, 0]), torch.full((6,), 1 / 6), "", out
    )
    total.backward()
    grad = model.decoder.dist_head[-1].bias.grad
    assert grad is not None and float(grad.abs().sum()) > 0


def test_the_contradictory_policy_turns_at_the_boundary_or_half_way_and_stays_back():
    h = np.array([1, 1, 1, -1])
    boundary = np.array([False, True, False, False])
    assert collect.contradictory_heading(h, 0, 8, boundary).tolist() == [1, -1, 1, -1]
    # After half the sequence (step 4 of 8) everything heads back.
    assert collect.contradictory_heading(h, 3, 8, np.zeros(4, bool)).tolist() == [-1, -1, -1, -1]
    # Back stays back, even at a boundary.
    assert collect.contradictory_heading(np.array([-1]), 5, 8, np.array([True])).tolist() == [-1]


def test_signed_distance_splits_moves_where_its_labels_do(tmp_path):
    """A SignedDist decoder predicting 0.05 x: under the reference's labels
    (moves from 0.05 m, no move labelled 0) that is a move along ±x, and the
    package says so; δ's 0.15 would call every candidate still."""
    torch.manual_seed(0)
    cfg = fixture.make_config("smoke", variant="signed-dist")
    model = fixture.UMPNet(cfg)
    with torch.no_grad():
        for p in model.decoder.parameters():
            p.zero_()
        model.decoder.bilinear_dist.bias.copy_(torch.tensor([0.05, 0.0, 0.0]))
    pkg = tmp_path / "signed"
    export_model(model, cfg, pkg, {"command": "test_runtime_semantics", "trained": False})
    meta = json.loads((pkg / "model.json").read_text())
    assert cfg.labels == "reference" and meta["signed_distance_threshold"] == 0.025
    for r in choose(pkg, "explore"):
        assert r["direction"][0] > 0.5 and r["aot"][r["candidates"].index(r["direction"])] == 1
    for r in choose(pkg, "goal"):
        assert r["direction"][0] < -0.5 and r["aot"][r["candidates"].index(r["direction"])] == -1
    meta["signed_distance_threshold"] = 0.15
    (pkg / "model.json").write_text(json.dumps(meta))
    assert all(set(r["aot"]) == {0} for r in choose(pkg, "goal"))
    meta["signed_distance_threshold"] = -1.0
    (pkg / "model.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="signed_distance_threshold"):
        umpnet.Policy(str(pkg))
