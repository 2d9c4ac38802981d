"""What the learner learns from and how: the replay's class balance, the
networks' view of the image, dense labels, the random grasps of collection,
and the update itself (held-out progress, mirrored batches, learner modes)."""

import dataclasses
import json

import numpy as np
import pytest
import torch
import umpnet
from umpnet_train import collect, diagnose, train
from umpnet_train.config import make_config
from umpnet_train.replay import Replay


def test_replay_balances_classes_and_drops_stale_references():
    r = Replay(8, (2, 2, 10))
    img = np.zeros((2, 2, 10), np.float32)
    ref = r.add_reference(img)
    for k, aot in enumerate([1, 1, 1, 1, 0, -1]):
        r.add_direction(img, [0, 0], [1, 0, 0], 0.2 * k, aot, ref)
    rng = np.random.default_rng(0)
    *_, aot = r.sample_directions(rng, 24)
    assert sorted(set(aot.tolist())) == [-1, 0, 1] and (aot == 1).sum() == 8
    *_, aot = r.sample_directions(rng, 24, "moved")
    assert len(aot) == 24 and (aot != 0).all()
    *_, aot = r.sample_directions(rng, 24, "binary")
    assert (aot == 0).sum() == 12
    with pytest.raises(ValueError, match="expected aot, binary or moved"):
        r.sample_directions(rng, 24, "all")
    for _ in range(8):  # overwrite the reference: every sample now points at a stale one
        r.add_reference(img)
    assert len(r.sample_directions(rng, 24)[-1]) == 0


def test_context_network_sees_the_whole_image_and_the_difference():
    from umpnet_train.models import Difference, UMPNet

    cur = torch.zeros(1, 96, 128, 10).permute(0, 3, 1, 2)
    ref = cur.clone()
    ref[:, 0] -= 0.05  # the point moved 5 cm along +x since the reference
    d = Difference()(cur, ref)
    assert torch.allclose(d[:, 0], torch.full_like(d[:, 0], 0.5)) and d[:, 1:].abs().max() == 0

    torch.manual_seed(0)
    obs = torch.randn(1, 96, 128, 10)
    far = obs.clone()
    far[0, 90:, 120:] += 1.0  # change only a far corner
    pixel = torch.tensor([[0, 0]])
    changed = {}
    for net in ["plain", "context"]:
        model = UMPNet(make_config("cpu-small", direction_net=net)).eval()
        with torch.no_grad():
            a = model.encoder(obs, obs, pixel)[1]
            b = model.encoder(far, obs, pixel)[1]
        changed[net] = float((a - b).abs().max())
    # A 3-level U-Net cannot see 90 pixels away; the global context can.
    assert changed["plain"] == 0.0 and changed["context"] > 0.0


def test_dense_batches_weigh_each_aot_class_equally():
    w = train.class_weights(torch.tensor([0, 0, 0, 2]), 3)
    np.testing.assert_allclose(w.numpy(), [1 / 6, 1 / 6, 1 / 6, 1 / 2])
    ranked = collect.unit(np.random.default_rng(0).normal(size=(2, 10, 3))).astype(np.float32)
    dirs = collect.dense_directions(ranked, 6, np.random.default_rng(1))
    assert dirs.shape == (2, 6, 3)
    np.testing.assert_array_equal(dirs[:, :3], ranked[:, :3])  # the policy's best half first
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0, rtol=1e-5)


def test_dense_label_training_and_diagnostics_on_a_tiny_package(tmp_path, capsys):
    import re

    out, pkg = tmp_path / "run", tmp_path / "package"
    args = ["--preset", "smoke", "--out", str(out), "--epochs", "2", "--dense-labels", "6", "--export", str(pkg)]
    assert train.main(args) == 0
    text = capsys.readouterr().out
    count = re.search(r"dense labels: (\d+) in", text)
    assert count and int(count.group(1)) > 0 and int(count.group(1)) % 6 == 0, text
    cfg = json.loads((pkg / "model.json").read_text())["config"]
    assert (cfg["dense_labels"], cfg["labels"]) == (6, "reference")
    # The diagnostics run on the package end to end and report shares.
    assert diagnose.main([str(pkg), "--episodes", "2", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    for split in ("train", "test"):
        s = report["splits"][split]
        assert s["exploration"]["episodes"] == 2 and set(s["swap"]) == {
            "learned/learned",
            "learned/oracle",
            "oracle/learned",
        }
        for key in ("aot_accuracy", "position_validity", "success"):
            v = s["goal"][key]
            assert v is None or 0.0 <= v <= 1.0, (key, v)
    assert report["mirror_average"] is False
    # Scored on the scene and its mirror image, as eval --mirror-average does.
    assert diagnose.main([str(pkg), "--episodes", "2", "--json", "--mirror-average"]) == 0
    mirrored = json.loads(capsys.readouterr().out)
    assert mirrored["mirror_average"] is True and mirrored["splits"]["test"]["goal"]["episodes"] == 2
    assert diagnose.main([str(tmp_path), "--episodes", "2"]) == 2  # not a package


def test_random_grasps_follow_the_released_rule():
    # Half the pixels on the floor (z = 0), half on an object 0.2 m up. A
    # random pixel is kept off the floor always, on it with probability 0.1,
    # so the floor's share is 0.5 * 0.1 / (0.5 + 0.5 * 0.1) = 1/11.
    image = np.zeros((8, 10, 10), np.float32)
    image[:, :5, 2] = 0.2
    image[:, 5:, 2] = 0.001  # below the 5 mm clearance: still floor
    rng = np.random.default_rng(0)
    picks = np.array([collect.random_pixel(image, rng) for _ in range(20_000)])
    on_floor = (picks % 10 >= 5).mean()
    assert abs(on_floor - 1 / 11) < 0.01, on_floor
    # Every pixel can be chosen, the floor's too.
    assert np.bincount(picks, minlength=80).min() > 0


def _dense_data(cfg, seed: int, sequences: int):
    """Replay buffers filled the way training fills them (random grasps on the
    object, random and probed directions, the reference's labels)."""
    from umpnet_train.models import UMPNet
    from umpnet_train.replay import DenseReplay

    env = umpnet.VecEnv(
        cfg.num_envs, category=collect.TRAIN_CATEGORIES, seed=seed, resolution=(cfg.height, cfg.width), copy=True
    )
    shape = (cfg.height, cfg.width, 10)
    replay, dense = Replay(4096, shape), DenseReplay(1024, shape, cfg.dense_labels)
    stats = {"sim_s": 0, "probe_s": 0, "positions": 0, "position_success": 0, "steps": 0, "dense_labels": 0}
    stats["aot_counts"] = [0, 0, 0]
    rng, model = np.random.default_rng(seed), UMPNet(cfg)
    for _ in range(sequences // cfg.num_envs):
        collect.collect(env, model, cfg, replay, dense, 0, rng, stats)
    return replay, dense


def _held_out_scores(model, replay, dense) -> tuple[float, float]:
    """(the training objective 100 MSE + CE, class-balanced AoT accuracy) over
    every held-out dense label."""
    n = len(dense)
    k = dense.vectors.shape[1]
    model.eval()
    with torch.no_grad():
        de, ae = model.encoder(
            collect.to_torch(dense.images[:n]),
            collect.to_torch(replay.ref_images[dense.ref[:n]]),
            collect.to_long(dense.pixels[:n]),
        )
        dist, logits = model.decoder(
            de.repeat_interleave(k, 0), ae.repeat_interleave(k, 0), collect.to_torch(dense.vectors[:n].reshape(-1, 3))
        )
    model.train()
    aot = dense.aot[:n].reshape(-1) + 1
    weights = train.class_weights(collect.to_long(aot), 3)
    ce = torch.nn.functional.cross_entropy(logits, collect.to_long(aot), reduction="none")
    mse = (dist - collect.to_torch(dense.dist[:n].reshape(-1))) ** 2
    objective = float(((100 * mse + ce) * weights).sum())
    pred = logits.argmax(1).numpy()
    accuracy = float(np.mean([np.mean(pred[aot == c] == c) for c in range(3) if (aot == c).any()]))
    return objective, accuracy


def test_a_short_seeded_run_of_the_real_update_learns_what_held_out_states_show():
    """The training update (train.Learner, as `train` runs it) on the direction
    network must lower the objective and raise the AoT accuracy on states of
    other scenes. A loop that does not update, or that updates the wrong way,
    leaves both where they started."""
    from umpnet_train.models import UMPNet

    collect.set_device(torch.device("cpu"))
    torch.manual_seed(0)
    cfg = make_config("smoke", dense_labels=8, num_envs=8, seq_start=6, seq_max=6, lr=3e-3)
    replay, dense = _dense_data(cfg, seed=0, sequences=240)
    held_replay, held_dense = _dense_data(cfg, seed=1000, sequences=80)
    model = UMPNet(cfg)
    learner = train.Learner(model, cfg)
    before = _held_out_scores(model, held_replay, held_dense)
    rng = np.random.default_rng(0)
    for _ in range(100):
        learner.update(replay, dense, rng, train_position=False)
    after = _held_out_scores(model, held_replay, held_dense)
    # Measured (seed 0): objective 11.2 -> 2.3, balanced AoT accuracy 0.25 -> 0.36;
    # without the optimiser step the objective rises to 54.
    assert after[0] < 0.5 * before[0], (before, after)
    assert after[1] > before[1] + 0.05, (before, after)


def test_mirrored_batches_are_the_mirrored_scenes_the_learner_would_see():
    """With --mirror 1 every sampled state is mirrored: the losses equal those
    of the same update on buffers mirrored by hand (columns reversed; x
    negated in the points, normals and directions; the grasp column
    reflected), drawn with the same random stream. A mirror that missed a
    batch kind (positions, executed moves, dense labels) or an array of one
    would differ. A share between 0 and 1 mirrors some states, and a share
    outside [0, 1] is refused by name."""
    import copy

    from umpnet_train.models import UMPNet

    collect.set_device(torch.device("cpu"))
    cfg = make_config("smoke", dense_labels=4, num_envs=4, seq_start=4, seq_max=4)
    replay, dense = _dense_data(cfg, seed=3, sequences=16)
    torch.manual_seed(0)
    model = UMPNet(cfg).eval()  # no batch statistics: the same batch gives the same losses

    def by_hand(images, pixels, vectors):
        images[...] = images[:, :, ::-1].copy()
        images[..., [0, 6]] *= -1
        pixels[:, 1] = images.shape[2] - 1 - pixels[:, 1]
        vectors[..., 0] *= -1

    seen = copy.deepcopy(replay), copy.deepcopy(dense)
    by_hand(seen[0].pos_images, seen[0].pos_pixels, np.zeros((1, 3)))
    by_hand(seen[0].dir_images, seen[0].dir_pixels, seen[0].dir_vectors)
    seen[0].ref_images[...] = seen[0].ref_images[:, :, ::-1].copy()
    seen[0].ref_images[..., [0, 6]] *= -1
    by_hand(seen[1].images, seen[1].pixels, seen[1].vectors)

    def run(share, buffers):
        mirrored = dataclasses.replace(cfg, mirror=share)
        out = train.losses(model, mirrored, *buffers, np.random.default_rng(7))
        return {k: float(v.detach()) for k, v in out.items()}

    plain, mirrored, expected = run(0.0, (replay, dense)), run(1.0, (replay, dense)), run(0.0, seen)
    assert {"loss/position", "loss/aot", "loss/dense_aot"} <= expected.keys()
    assert mirrored.keys() == expected.keys()
    for k in expected:
        assert np.isclose(mirrored[k], expected[k], rtol=1e-4, atol=1e-6), (k, mirrored[k], expected[k])
    assert any(not np.isclose(plain[k], expected[k], rtol=1e-4) for k in expected if k.startswith("loss/"))
    half = run(0.5, (replay, dense))
    assert all(np.isfinite(v) for v in half.values()) and half != plain
    with pytest.raises(ValueError, match="mirror 1.5: expected a share between 0 and 1"):
        make_config("smoke", mirror=1.5)


def test_learner_modes_update_the_same_fp32_weights():
    """Every learner mode trains the fp32 model that checkpoints and export
    read; an unknown mode is an error naming the choices."""
    from umpnet_train.models import UMPNet

    collect.set_device(torch.device("cpu"))
    cfg = make_config("smoke", dense_labels=4, num_envs=4)
    replay, dense = _dense_data(cfg, seed=3, sequences=8)
    for mode in ("fp32", "channels-last", "bf16"):
        torch.manual_seed(0)
        model = UMPNet(cfg)
        first = {k: v.clone() for k, v in model.state_dict().items()}
        out = train.Learner(model, cfg, mode).update(replay, dense, np.random.default_rng(0))
        assert np.isfinite(float(out["loss/total"])), mode
        changed = [
            k for k, v in model.state_dict().items() if v.dtype.is_floating_point and not torch.equal(v, first[k])
        ]
        assert changed and all(model.state_dict()[k].dtype == torch.float32 for k in changed), mode
    with pytest.raises(ValueError, match="channels-last"):
        train.Learner(UMPNet(cfg), cfg, "fp16")
    with pytest.raises(ValueError, match="learner 'fp16'"):
        make_config("smoke", learner="fp16")


def test_glass_depth_mix_gives_a_share_of_the_environments_each_misreading():
    """--glass-depth-mix: round(mix * n) environments misread glass, half
    through it and half not at all; the rest read the pane. The share is
    checked like --mirror's."""
    from umpnet_train.config import glass_depths

    assert glass_depths(4, 0.0) == ["surface"] * 4
    assert glass_depths(4, 0.5) == ["through", "missing", "surface", "surface"]
    assert glass_depths(16, 0.25).count("surface") == 12
    assert glass_depths(3, 1.0) == ["through", "missing", "through"]
    assert make_config("smoke", glass_depth_mix=0.5).glass_depth_mix == 0.5
    with pytest.raises(ValueError, match="glass_depth_mix 1.5: expected a share between 0 and 1"):
        make_config("smoke", glass_depth_mix=1.5)
