"""The training pipeline end to end on the smoke preset: train, checkpoint,
resume, export, and load the package from Rust."""

import dataclasses
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
from umpnet_train.config import Config, config_from_checkpoint, make_config
from umpnet_train.replay import Replay

ROOT = Path(__file__).resolve().parents[2]


def test_presets_and_config_errors():
    cfg = make_config("paper")
    assert (cfg.height, cfg.width, cfg.replay_size, cfg.batch_direction) == (480, 640, 6400, 24)
    assert cfg.dist_loss_weight == 100.0
    with pytest.raises(ValueError, match="unknown preset"):
        make_config("huge")
    with pytest.raises(ValueError, match="unknown config fields"):
        make_config("smoke", lr_typo=1.0)
    with pytest.raises(ValueError, match="random_grasp 'objects': expected one of 'released', 'object'"):
        make_config("smoke", random_grasp="objects")
    # A checkpoint from before the field resumes with the grasps it was trained with.
    saved = dataclasses.asdict(make_config("cpu-small"))
    assert config_from_checkpoint(saved).random_grasp == "released"
    del saved["random_grasp"]
    assert config_from_checkpoint(saved).random_grasp == "object"


def test_every_config_field_is_a_flag_with_its_choices(capsys):
    """The command line is generated from Config: each field is one flag,
    parsed to the field's type, and a closed set's other names are refused."""
    for f in dataclasses.fields(Config):
        if not f.metadata.get("cli", True):
            continue
        default = f.default
        text = ",".join(str(v) for v in default) if isinstance(default, tuple) else str(default)
        flag = "--" + f.name.replace("_", "-")
        argv = ["--out", "x", flag] if isinstance(default, bool) else ["--out", "x", flag, text]
        cfg, _ = train.parse_args(argv)
        assert getattr(cfg, f.name) == (True if isinstance(default, bool) else default), f.name
        assert f.metadata["help"], f.name
    with pytest.raises(SystemExit) as e:
        train.parse_args(["--out", "x", "--learner", "fp64"])
    assert e.value.code == 2 and "invalid choice: 'fp64'" in capsys.readouterr().err


def test_direction_widths_flag(capsys):
    cfg, _ = train.parse_args(["--out", "x", "--direction-widths", "8,16,32,64"])
    assert cfg.direction_widths == (8, 16, 32, 64) and cfg.position_widths == (8, 16, 32)
    with pytest.raises(SystemExit) as e:
        train.parse_args(["--out", "x", "--direction-widths", "8,0"])
    assert e.value.code == 2 and "expected positive integers" in capsys.readouterr().err


def test_curriculum_and_schedules():
    cfg = make_config("paper")
    assert collect.sequence_length(cfg, 0) == 4 and collect.sequence_length(cfg, 999) == 4
    assert collect.sequence_length(cfg, 1000) == 6 and collect.sequence_length(cfg, 1400) == 8
    assert collect.sequence_length(cfg, 10**6) == 20
    assert collect.epsilon((1.0, 0.1), 0, 300, 0) == 1.0 and abs(collect.epsilon((1.0, 0.1), 0, 300, 150) - 0.55) < 1e-9
    assert collect.epsilon((1.0, 0.1), 0, 300, 301) == 0.1
    # The reference's warm-up: random until the start epoch, then the decay.
    assert collect.epsilon((1.0, 0.2), 800, 500, 799) == 1.0
    assert abs(collect.epsilon((1.0, 0.2), 800, 500, 1050) - 0.6) < 1e-9


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


def test_smoke_training_resume_export_and_rust_load(tmp_path):
    out = tmp_path / "run"
    pkg = tmp_path / "package"
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "2"]) == 0
    ck = out / "checkpoint.pt"
    assert ck.is_file()
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "3", "--resume", "--export", str(pkg)]) == 0
    meta = json.loads((pkg / "model.json").read_text())
    assert meta["provenance"]["epochs"] == 3 and meta["provenance"]["seed"] == 0
    segments = meta["provenance"]["segments"]
    assert [seg["from_epoch"] for seg in segments] == [0, 2]  # the first run and its resume
    assert all(seg["git_commit"] == meta["provenance"]["git_commit"] for seg in segments)
    assert meta["export_check"]["max_abs_diff_onnx_vs_torch"] < 1e-3
    pol = umpnet.Policy(str(pkg))
    assert pol.resolution == (48, 64)
    umpnet_bin = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
    res = subprocess.run(
        [umpnet_bin, "--json", "explore", "--category", "Door", "--policy", f"smoke={pkg}", "--steps", "2"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["policy"] == "smoke"


def test_a_time_limit_stops_with_a_checkpoint_and_the_export(tmp_path, capsys):
    out, pkg = tmp_path / "run", tmp_path / "package"
    args = ["--preset", "smoke", "--out", str(out), "--epochs", "40", "--time-limit", "1e-9", "--export", str(pkg)]
    assert train.main(args) == 0
    assert torch.load(out / "checkpoint.pt", weights_only=False)["epoch"] == 1
    assert json.loads((pkg / "model.json").read_text())["provenance"]["epochs"] == 1
    assert "stopped after epoch 1 of 40" in capsys.readouterr().out
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "2", "--resume"]) == 0
    assert torch.load(out / "checkpoint.pt", weights_only=False)["epoch"] == 2
    with pytest.raises(SystemExit):
        train.main(["--preset", "smoke", "--out", str(out), "--time-limit", "0"])
    assert "--time-limit 0.0: expected a positive number" in capsys.readouterr().err


def test_resume_without_checkpoint_is_an_error(tmp_path, capsys):
    assert train.main(["--preset", "smoke", "--out", str(tmp_path), "--resume"]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_export_cli_rejects_missing_checkpoint(tmp_path):
    res = subprocess.run(
        [sys.executable, "-m", "umpnet_train.export", str(tmp_path / "nope.pt"), str(tmp_path / "out")],
        capture_output=True,
        text=True,
        check=False,
        cwd=ROOT / "train_py",
    )
    assert res.returncode == 2 and "no such checkpoint" in res.stderr


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


def test_replay_buffer_round_trips_through_resume(tmp_path, capsys):
    out = tmp_path / "run"
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "2", "--save-replay"]) == 0
    saved = Replay(256, (48, 64, 10))
    assert saved.load(out / "replay.npz") == 2 and len(saved) > 0
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "3", "--resume", "--save-replay"]) == 0
    assert f"with {len(saved)} direction samples" in capsys.readouterr().out
    grown = Replay(256, (48, 64, 10))
    assert grown.load(out / "replay.npz") == 3 and len(grown) > len(saved)
    n = len(saved)
    assert np.array_equal(grown.dir_images[:n], saved.dir_images[:n])  # the old samples survived the resume
    with pytest.raises(ValueError, match="expected"):
        Replay(256, (24, 32, 10)).load(out / "replay.npz")


def test_context_network_sees_the_whole_image_and_the_difference():
    import torch
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


def test_checkpoints_from_before_the_context_network_still_export(tmp_path, capsys):
    import torch

    out = tmp_path / "run"
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "1", "--direction-net", "plain"]) == 0
    ck = torch.load(out / "checkpoint.pt", weights_only=False)
    del ck["config"]["direction_net"]  # as written by earlier versions
    torch.save(ck, out / "checkpoint.pt")
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "2", "--resume"]) == 2
    assert "add --direction-net plain" in capsys.readouterr().err
    from umpnet_train import export

    assert export.main([str(out / "checkpoint.pt"), str(tmp_path / "pkg")]) == 0
    meta = json.loads((tmp_path / "pkg" / "model.json").read_text())
    assert meta["config"]["direction_net"] == "plain"


def test_dense_batches_weigh_each_aot_class_equally():
    import torch

    w = train.class_weights(torch.tensor([0, 0, 0, 2]), 3)
    np.testing.assert_allclose(w.numpy(), [1 / 6, 1 / 6, 1 / 6, 1 / 2])
    ranked = collect.unit(np.random.default_rng(0).normal(size=(2, 10, 3))).astype(np.float32)
    dirs = collect.dense_directions(ranked, 6, np.random.default_rng(1))
    assert dirs.shape == (2, 6, 3)
    np.testing.assert_array_equal(dirs[:, :3], ranked[:, :3])  # the policy's best half first
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0, rtol=1e-5)


def test_dense_label_training_and_diagnostics_on_a_tiny_package(tmp_path, capsys):
    import re

    from umpnet_train import diagnose

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


def test_diagnostic_measures_on_known_values():
    from umpnet_train import diagnose

    assert diagnose.spearman(np.array([1.0, 2, 3]), np.array([10.0, 20, 30])) == pytest.approx(1.0)
    assert diagnose.spearman(np.array([1.0, 2, 3]), np.array([3.0, 2, 1])) == pytest.approx(-1.0)
    assert diagnose.spearman(np.array([1.0, 2, 3]), np.array([5.0, 5, 5])) is None
    # Toward the reference is -1, away +1, not moved 0.
    aot = diagnose.true_aot(0.5, np.array([0.3, 0.8, 0.5]), 0.0, np.array([True, True, False]))
    np.testing.assert_array_equal(aot, [-1, 1, 0])
    # Progress: away from the start when exploring, toward the goal otherwise.
    np.testing.assert_allclose(diagnose.progress(0.5, np.array([0.8, 0.2]), 0.0, 1.0, "exploration"), [0.3, -0.3])
    np.testing.assert_allclose(diagnose.progress(0.5, np.array([0.8, 0.2]), 0.0, 1.0, "goal"), [0.3, -0.3])
    np.testing.assert_allclose(diagnose.progress(0.5, np.array([0.8, 0.2]), 0.0, 0.0, "goal"), [-0.3, 0.3])


def test_periodic_evaluation_logs_the_diagnostics(tmp_path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out = tmp_path / "run"
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "1", "--eval-every", "1"]) == 0
    tags = EventAccumulator(str(out / "tb")).Reload().Tags()["scalars"]
    for tag in (
        "diagnose/test/goal/aot_accuracy",
        "diagnose/train/exploration/position_validity",
        "diagnose/test/goal_success/learned/oracle",
    ):
        assert tag in tags, sorted(tags)
    assert any(t.startswith("eval/goal/") for t in tags), sorted(tags)


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


def test_position_from_another_run_stays_fixed_while_the_direction_nets_train(tmp_path, capsys):
    import torch

    donor, run = tmp_path / "donor", tmp_path / "run"
    assert train.main(["--preset", "smoke", "--out", str(donor), "--epochs", "2", "--seed", "1"]) == 0
    assert train.main(["--preset", "smoke", "--out", str(run), "--epochs", "2"]) == 0
    before = torch.load(run / "checkpoint.pt", weights_only=False)
    donor_ck = torch.load(donor / "checkpoint.pt", weights_only=False)
    args = [
        "--preset",
        "smoke",
        "--out",
        str(run),
        "--epochs",
        "4",
        "--resume",
        "--position-from",
        str(donor / "checkpoint.pt"),
    ]
    assert train.main(args) == 0
    after = torch.load(run / "checkpoint.pt", weights_only=False)
    for k, v in after["model"].items():
        if k.startswith("position."):
            assert torch.equal(v, donor_ck["model"][k]), k  # weights and BatchNorm statistics
    changed = [
        k for k, v in after["model"].items() if k.startswith("encoder.") and not torch.equal(v, before["model"][k])
    ]
    assert changed, "the direction nets did not train"
    assert after["config"]["freeze_position"] is True
    assert after["provenance"]["position_from"]["checkpoint"] == str(donor / "checkpoint.pt")
    assert after["provenance"]["position_from"]["epochs"] == 2
    capsys.readouterr()
    # A missing file, a file that is not a checkpoint, another architecture: named, exit 2.
    junk = tmp_path / "junk.pt"
    junk.write_text("not a checkpoint")
    from umpnet_train.models import UMPNet

    wide = tmp_path / "wide.pt"
    cfg = make_config("cpu-small")
    torch.save({"model": UMPNet(cfg).state_dict(), "config": dataclasses.asdict(cfg)}, wide)
    for path, message in [
        (tmp_path / "missing.pt", "no such file"),
        (junk, "cannot be read as a checkpoint"),
        (wide, "widths (8, 16, 32)) does not match this run's ([8, 16])"),
    ]:
        assert train.main([*args[:-1], str(path)]) == 2
        err = capsys.readouterr().err
        assert f"--position-from {path}" in err and message in err, err


def _fields_data(seed: int, resets: int):
    """Observations of seeded scenes with their simulated articulation flow."""
    env = umpnet.VecEnv(
        8, category=["Microwave", "StorageFurniture", "Door", "Laptop"], resolution=(48, 64), seed=seed, copy=True
    )
    images, flows = [], []
    for _ in range(resets):
        images.append(env.reset()["image"])
        flows.append(env.articulation_fields()["flow"])
    return np.concatenate(images), np.concatenate(flows)


def test_the_auxiliary_flow_head_learns_the_articulation_flow_of_unseen_scenes():
    import torch
    from umpnet_train.models import PositionNet

    collect.set_device(torch.device("cpu"))
    torch.manual_seed(0)
    images, flows = _fields_data(seed=0, resets=8)
    held_images, held_flows = _fields_data(seed=1, resets=2)  # other instances, poses and joint states
    net = PositionNet((8, 16, 32), fields=True)
    opt = torch.optim.Adam(net.parameters(), lr=3e-3)

    def held_out_cosine() -> float:
        out = {}
        net.eval()
        with torch.no_grad():
            train.flow_losses(net.forward_fields(torch.from_numpy(held_images))[1][:, :3], held_flows, out, "")
        net.train()
        return float(out["metric/flow_cosine"])

    before = held_out_cosine()
    rng = np.random.default_rng(0)
    for _ in range(60):
        idx = rng.choice(len(images), 16)
        _, aux = net.forward_fields(torch.from_numpy(images[idx]))
        loss = train.flow_losses(aux[:, :3], flows[idx], {}, "", aux[:, 3])
        opt.zero_grad()
        loss.backward()
        opt.step()
    after = held_out_cosine()
    # Measured: 0.23 before, 0.83 after 50 steps.
    assert after > 0.6 and after > before + 0.3, (before, after)


def test_training_with_auxiliary_fields_runs_and_exports_the_same_package_contract(tmp_path):
    import torch

    out, pkg = tmp_path / "run", tmp_path / "package"
    args = ["--preset", "smoke", "--epochs", "2", "--aux-fields", "1", "--out", str(out), "--export", str(pkg)]
    assert train.main(args) == 0
    ck = torch.load(out / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert config_from_checkpoint(ck["config"]).aux_fields == 1.0
    assert any(k.startswith("position.fields_head") for k in ck["model"])
    assert any(k.startswith("encoder.flow_head") for k in ck["model"])
    # The heads are for training only: the package is the one the runtime knows.
    meta = json.loads((pkg / "model.json").read_text())
    assert meta["export_check"]["max_abs_diff_onnx_vs_torch"] < 1e-3
    assert umpnet.Policy(str(pkg)).resolution == (48, 64)
    with pytest.raises(SystemExit):
        train.parse_args(["--out", str(out), "--aux-fields", "1", "--ray", "2"])


def test_scaled_flow_training_and_the_single_frame_joint_fit(tmp_path):
    """`--aux-flow scaled`: the fields head learns flow x relative speed (a
    squared error, not a cosine), and frame_joint's rigid fit recovers a
    hinge's axis and origin, or a slide's axis, from such flow; from unit flow
    on a flat part no hinge can be told, and it says prismatic."""
    import torch
    from umpnet_train import frame_joint

    # The fit on exact flows: a hinge along z through (0.3, 0.1, 0), a slide along x.
    rng = np.random.default_rng(0)
    points = np.c_[rng.uniform(0.35, 0.9, 200), np.full(200, 0.1), rng.uniform(0.1, 0.8, 200)]
    axis, origin = np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.1, 0.0])
    velocity = np.cross(axis, points - origin)
    hinge = frame_joint.fit_joint(points, velocity / np.linalg.norm(velocity, axis=1).max())
    assert hinge["type"] == "revolute" and frame_joint.angle_deg(hinge["axis"], axis) < 1e-3
    assert np.allclose(hinge["origin"][:2], origin[:2], atol=1e-6)
    unit = velocity / np.linalg.norm(velocity, axis=1, keepdims=True)  # the same vector on a flat door
    assert frame_joint.fit_joint(points, unit)["type"] == "prismatic"
    slide = frame_joint.fit_joint(points, np.tile([0.8, 0.0, 0.0], (200, 1)) + rng.normal(0, 0.01, (200, 3)))
    assert slide["type"] == "prismatic" and frame_joint.angle_deg(slide["axis"], np.array([1.0, 0, 0])) < 2

    # The scaled target reaches the loss as a squared error.
    target = np.zeros((1, 4, 4, 3), np.float32)
    target[0, 1, 1] = [0.5, 0.0, 0.0]
    pred = torch.zeros(1, 3, 4, 4)
    out = {}
    train.flow_losses(pred, target, out, "p_", scaled=True)
    assert float(out["loss/p_flow"]) == pytest.approx(0.25)
    train.flow_losses(pred, target, out, "p_", scaled=False)
    assert float(out["loss/p_flow"]) == pytest.approx(1.0)  # 1 - cosine of a zero prediction

    run = tmp_path / "run"
    args = ["--preset", "smoke", "--epochs", "2", "--aux-fields", "1", "--aux-flow", "scaled", "--out", str(run)]
    assert train.main(args) == 0
    report = frame_joint.measure(run / "checkpoint.pt", "test", 1)
    assert report["all"]["n"] >= 5 and 0 <= report["all"]["median_axis_error_deg"] <= 90
    with pytest.raises(ValueError, match="without --aux-fields"):
        plain = tmp_path / "plain"
        assert train.main(["--preset", "smoke", "--epochs", "1", "--out", str(plain)]) == 0
        frame_joint.measure(plain / "checkpoint.pt", "test", 1)


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
    import torch

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
    import torch
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

    import torch
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
    import torch
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


def test_a_bad_preset_or_learner_is_a_usage_error_not_a_traceback(capsys):
    for argv in (["--preset", "tiny"], ["--learner", "fp16"]):
        with pytest.raises(SystemExit) as e:
            train.parse_args([*argv, "--out", "runs/x"])
        assert e.value.code == 2
    err = capsys.readouterr().err
    assert "unknown preset 'tiny'" in err and "--learner: invalid choice: 'fp16'" in err, err


def test_a_config_file_sits_between_the_preset_and_the_flags_and_repeats_a_run(tmp_path, capsys):
    """`--config FILE` (TOML or JSON): over the preset, under the flags. A run's
    config.json and a package's model.json give back the config they record;
    a wrong field or value is a usage error naming the file and the field."""
    toml = tmp_path / "run.toml"
    toml.write_text('preset = "smoke"\nepochs = 7\ndirection_widths = [8, 16]\nlr = 1\ncategories = ["Door"]\n')
    cfg, args = train.parse_args(["--config", str(toml), "--out", "x", "--epochs", "9"])
    smoke = make_config("smoke")
    assert args.preset == "smoke" and cfg.epochs == 9 and cfg.direction_widths == (8, 16)
    assert cfg.lr == 1.0 and isinstance(cfg.lr, float) and cfg.categories == ["Door"]
    assert cfg.height == smoke.height and cfg.seq_max == smoke.seq_max  # the rest is the preset's
    # A run writes its whole config; --config on it makes the same Config.
    out = tmp_path / "run"
    assert train.main(["--config", str(toml), "--epochs", "1", "--out", str(out)]) == 0
    again, _ = train.parse_args(["--config", str(out / "config.json"), "--out", "y"])
    assert again == dataclasses.replace(cfg, epochs=1)
    shipped, _ = train.parse_args(["--config", str(ROOT / "models" / "umpnet-small" / "model.json"), "--out", "z"])
    recorded = json.loads((ROOT / "models" / "umpnet-small" / "model.json").read_text())["config"]
    assert shipped.epochs == recorded["epochs"] and list(shipped.direction_widths) == recorded["direction_widths"]
    for text, message in (
        ("epoch = 3", "unknown field 'epoch'; did you mean 'epochs'?"),
        ('epochs = "3"', "epochs '3': expected int"),
        ("adam_betas = [0.9]", "adam_betas [0.9]: expected a list of 2 floats"),
        ("epochs =", "not valid TOML"),
        ('preset = "tiny"', "preset 'tiny': expected one of"),
    ):
        toml.write_text(text + "\n")
        with pytest.raises(SystemExit) as e:
            train.parse_args(["--config", str(toml), "--out", "x"])
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert f"--config {toml}: {message}" in err, err
    with pytest.raises(SystemExit):
        train.parse_args(["--config", str(tmp_path / "missing.json"), "--out", "x"])
    assert "cannot read it" in capsys.readouterr().err


def test_the_paper_direction_net_is_the_papers_and_exports_the_same_contract(tmp_path):
    """`--direction-net paper` (the paper preset's): seven conv stages to a
    flattened 512 x 7 x 10 map at 480 x 640, 256 features per branch, an action
    MLP of 128 per branch and 1024-1024-1024 decoders; whole-image features, so
    the grasp pixel changes nothing and the AoT branch alone reads the
    reference. A smoke run of it exports a package the Rust runtime scores."""
    import torch
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


@pytest.mark.parametrize("package", ["umpnet-small", "umpnet-gpu-medium"])
def test_a_shipped_package_is_what_its_committed_checkpoints_export(tmp_path, package):
    """The checkpoints under models/checkpoints are the sources of the shipped
    networks: exported again, every network answers as the shipped one."""
    import onnxruntime as ort
    from umpnet_train import export, joint_net

    models = ROOT / "models"
    shipped = models / package
    assert export.main([str(models / "checkpoints" / package / "checkpoint.pt"), str(tmp_path)]) == 0
    joint_net.export(models / "checkpoints" / "joint" / "joint.pt", tmp_path)
    rng = np.random.default_rng(0)
    near = np.array([0, -0.5, 0.3, 0.5, 0.5, 0.5, 0, 0, 1, 2.2], np.float32)  # about a real observation

    def image():
        return (rng.normal(size=(2, 96, 128, 10)) * 0.3 + near).astype(np.float32)

    embedding = json.loads((shipped / "model.json").read_text())["embedding"]
    inputs = {
        "position": {"observation": image()},
        "joint": {"observation": image()},
        "direction_encoder": {
            "observation": image(),
            "reference": image(),
            "pixel": np.array([[40, 60], [10, 100]], np.int64),
        },
        "direction_decoder": {
            "dist_embedding": rng.normal(size=(5, embedding)).astype(np.float32),
            "aot_embedding": rng.normal(size=(5, embedding)).astype(np.float32),
            "direction": rng.normal(size=(5, 3)).astype(np.float32),
        },
    }
    for net, feed in inputs.items():
        ours, theirs = (
            ort.InferenceSession(str(folder / f"{net}.onnx")).run(None, feed) for folder in (tmp_path, shipped)
        )
        for a, b in zip(ours, theirs, strict=True):
            np.testing.assert_allclose(a, b, atol=1e-4, err_msg=f"{package}/{net}.onnx")


def test_a_checkpoint_without_optimiser_state_resumes_at_its_scheduled_rate(tmp_path, capsys):
    """umpnet_train.candidates drops Adam's state from the checkpoints it writes."""
    out = tmp_path / "run"
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "2"]) == 0
    ck = torch.load(out / "checkpoint.pt", map_location="cpu", weights_only=False)
    del ck["optimizer"], ck["scheduler"]
    torch.save(ck, out / "checkpoint.pt")
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "3", "--resume"]) == 0
    assert "no optimiser state" in capsys.readouterr().err
    resumed = torch.load(out / "checkpoint.pt", map_location="cpu", weights_only=False)
    assert resumed["epoch"] == 3 and "optimizer" in resumed
