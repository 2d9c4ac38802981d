"""The paper's baselines and the paper's own direction network: each trains
on the smoke preset and exports a package the Rust runtime serves, with the
behaviour that sets it apart (a direction filter, one regressed direction,
moves collected from another policy)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import umpnet
from umpnet_train import collect, train
from umpnet_train.config import make_config

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("variant", ["single-step", "aot-only", "signed-dist", "where2act"])
def test_baseline_variants_export_packages_the_runtime_accepts(tmp_path, variant):
    pkg = tmp_path / "package"
    args = ["--preset", "smoke", "--epochs", "1", "--variant", variant, "--out", str(tmp_path), "--export", str(pkg)]
    assert train.main(args) == 0
    meta = json.loads((pkg / "model.json").read_text())
    assert meta["variant"] == variant and meta["uses_reference"] == (variant not in ("single-step", "where2act"))
    pol = umpnet.Policy(str(pkg))
    h, w = pol.resolution
    rng = np.random.default_rng(0)
    img = rng.normal(size=(2, h, w, 10)).astype(np.float32)
    out = pol.direction_batch(img, img, np.array([[1, 2], [3, 4]]), mode="goal")
    assert len(out) == 2 and all(len(o["distance"]) >= 64 for o in out)
    # The scores depend on the candidate direction (a decoder that ignored it would rank nothing).
    assert all(len({round(d, 6) for d in o["distance"]}) > 1 for o in out)


def test_where2act_filter_keeps_directions_within_90_degrees_of_the_normal(tmp_path):
    pkg = tmp_path / "package"
    args = ["--preset", "smoke", "--epochs", "1", "--variant", "where2act", "--out", str(tmp_path)]
    assert train.main(args) == 0
    res = subprocess.run(
        [sys.executable, "-m", "umpnet_train.export", str(tmp_path / "checkpoint.pt"), str(pkg),
         "--direction-filter", "normal90"],
        capture_output=True, text=True, check=False, cwd=ROOT / "train_py",
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert json.loads((pkg / "model.json").read_text())["direction_filter"] == "normal90"
    pol = umpnet.Policy(str(pkg))
    h, w = pol.resolution
    img = np.zeros((1, h, w, 10), np.float32)
    img[..., 9] = 2.0
    img[..., 8] = 1.0  # every surface faces +z
    out = pol.direction_batch(img, img, np.array([[h // 2, w // 2]]), mode="explore")[0]
    assert out["direction"][2] >= 0.0
    for d, dist in zip(out["candidates"], out["distance"], strict=True):
        if d[2] < 0:
            assert dist == -1.0


def test_inverse_baseline_regresses_one_direction_and_refuses_exploration(tmp_path):
    pkg = tmp_path / "package"
    args = ["--preset", "smoke", "--epochs", "2", "--variant", "inverse", "--out", str(tmp_path), "--export", str(pkg)]
    assert train.main(args) == 0
    meta = json.loads((pkg / "model.json").read_text())
    assert meta["branches"] == ["inverse"] and meta["decoder_outputs"] == ["predicted_direction"]
    pol = umpnet.Policy(str(pkg))
    h, w = pol.resolution
    rng = np.random.default_rng(1)
    cur = rng.normal(size=(2, h, w, 10)).astype(np.float32)
    goal = rng.normal(size=(2, h, w, 10)).astype(np.float32)
    out = pol.direction_batch(cur, goal, np.array([[1, 2], [3, 4]]), mode="goal")
    for o in out:
        d = np.array(o["direction"])
        assert abs(np.linalg.norm(d) - 1.0) < 1e-4 and len(o["candidates"]) == 1
    with pytest.raises(ValueError, match="only the goal task"):
        pol.direction_batch(cur, goal, np.array([[1, 2], [3, 4]]), mode="explore")
    umpnet_bin = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
    res = subprocess.run(
        [umpnet_bin, "explore", "--category", "Door", "--policy", f"inv={pkg}", "--steps", "2"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert res.returncode == 2 and "serves only the goal task" in res.stderr
    res = subprocess.run(
        [umpnet_bin, "--json", "goal", "--category", "Door", "--policy", f"inv={pkg}", "--steps", "2"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert len(json.loads(res.stdout)["steps"]) == 2


def test_the_paper_direction_net_is_the_papers_and_exports_the_same_contract(tmp_path):
    """`--direction-net paper` (the paper preset's): seven conv stages to a
    flattened 512 x 7 x 10 map at 480 x 640, 256 features per branch, an action
    MLP of 128 per branch and 1024-1024-1024 decoders; whole-image features, so
    the grasp pixel changes nothing and the AoT branch alone reads the
    reference. A smoke run of it exports a package the Rust runtime scores."""
    from torch import nn
    from umpnet_train.models import UMPNet

    paper = UMPNet(make_config("paper"))
    tower = paper.encoder.aot
    assert len(tower.stages) == 7 and tower.features[0].in_features == 512 * 7 * 10
    assert tower.features[-1].out_features == 256 and tower.stages[0][0].in_channels == 20
    assert paper.encoder.dist.stages[0][0].in_channels == 10
    hidden = [m.out_features for m in paper.decoder.dist_head if isinstance(m, nn.Linear)]
    assert hidden == [1024, 1024, 1024, 1] and paper.decoder.aot_head[-1].out_features == 3
    assert [m.out_features for m in paper.decoder.aot_action if isinstance(m, nn.Linear)] == [128, 128, 128]
    del paper

    model = UMPNet(make_config("cpu-small", direction_net="paper")).eval()
    torch.manual_seed(0)
    obs, ref = torch.randn(1, 96, 128, 10), torch.randn(1, 96, 128, 10)
    with torch.no_grad():
        a = model.encoder(obs, ref, torch.tensor([[0, 0]]))
        b = model.encoder(obs, ref, torch.tensor([[50, 70]]))
        c = model.encoder(obs, obs, torch.tensor([[0, 0]]))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert torch.equal(a[0], c[0]) and not torch.allclose(a[1], c[1])
    with pytest.raises(ValueError, match="below one pixel"):
        make_config("smoke", direction_net="paper")

    pkg = tmp_path / "package"
    args = ["--preset", "smoke", "--epochs", "1", "--direction-net", "paper", "--paper-widths", "8,16,32,64",
            "--out", str(tmp_path / "run"), "--export", str(pkg)]  # fmt: skip
    assert train.main(args) == 0
    meta = json.loads((pkg / "model.json").read_text())
    assert meta["config"]["direction_net"] == "paper" and meta["export_check"]["max_abs_diff_onnx_vs_torch"] < 1e-3
    pol = umpnet.Policy(str(pkg))
    h, w = pol.resolution
    img = np.random.default_rng(0).normal(size=(2, h, w, 10)).astype(np.float32)
    out = pol.direction_batch(img, img, np.array([[1, 2], [3, 4]]), mode="explore")
    assert len(out) == 2 and all(len(o["distance"]) >= 64 for o in out)
    # The decoder reads the candidate direction (one that did not would rank nothing).
    with torch.no_grad():
        dist, logits = model.decoder(a[0].expand(2, -1), a[1].expand(2, -1), torch.eye(3)[:2])
    assert not torch.allclose(dist[0], dist[1]) and not torch.allclose(logits[0], logits[1])


def test_inverse_learns_from_a_policys_own_moves(tmp_path, fixture_package):
    """--inverse-data PACKAGE: the Inverse baseline's collected moves are that
    policy's (toward the start where the contradictory policy turns back),
    as the paper trains Inverse; without it, uniformly random moves."""
    policy = collect.data_policy(fixture_package, (48, 64), seed=0)
    env = umpnet.VecEnv(4, category="Door", resolution=(48, 64), seed=3)
    env.reset()
    obs, _ = env.step_position(np.array(env.scripted_actions("oracle")))
    rng = np.random.default_rng(0)
    wanted = np.array([0, 1, -1, 1])
    dirs, _ = collect.choose_directions(None, "inverse", obs, wanted, 0.0, rng, data=policy)
    pixels = obs["gripper_pixel"].clip(min=0)
    replay = umpnet.Policy(fixture_package, seed=0)
    expected = {}
    for mode, rows in (("goal", [2]), ("explore", [0, 1, 3])):
        for i, d in zip(rows, replay.direction_batch(obs["image"][rows], obs["reference"][rows], pixels[rows], mode)):
            expected[i] = d["direction"]
    for i in range(4):
        if expected[i] is not None:
            assert np.allclose(dirs[i], expected[i], atol=1e-6), i
    with pytest.raises(ValueError, match="takes"):
        collect.data_policy(fixture_package + "/", (96, 128), seed=0)
    with pytest.raises(SystemExit):
        train.main(["--preset", "smoke", "--out", str(tmp_path), "--inverse-data", fixture_package])
    args = ["--preset", "smoke", "--epochs", "1", "--variant", "inverse", "--inverse-data", fixture_package,
            "--out", str(tmp_path / "run")]  # fmt: skip
    assert train.main(args) == 0
