"""The training pipeline end to end on the smoke preset: train, checkpoint,
resume, export, and load the package from Rust; the shipped packages are
what their committed checkpoints export."""

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
from umpnet_train import train
from umpnet_train.config import make_config
from umpnet_train.replay import Replay

ROOT = Path(__file__).resolve().parents[2]


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


def test_checkpoints_from_before_the_context_network_still_export(tmp_path, capsys):
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


def test_position_from_another_run_stays_fixed_while_the_direction_nets_train(tmp_path, capsys):
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


def test_freeze_direction_trains_the_grasp_alone(tmp_path, capsys):
    run = tmp_path / "run"
    assert train.main(["--preset", "smoke", "--out", str(run), "--epochs", "2"]) == 0
    before = torch.load(run / "checkpoint.pt", weights_only=False)
    args = ["--preset", "smoke", "--out", str(run), "--epochs", "4", "--resume", "--freeze-direction"]
    assert train.main(args) == 0
    after = torch.load(run / "checkpoint.pt", weights_only=False)
    # Weights and BatchNorm statistics alike: the direction nets ran only to label grasps.
    frozen = [k for k in after["model"] if not k.startswith("position.")]
    assert frozen and all(torch.equal(after["model"][k], before["model"][k]) for k in frozen)
    assert any(
        not torch.equal(v, before["model"][k]) for k, v in after["model"].items() if k.startswith("position.")
    ), "the position net did not train"
    assert after["config"]["freeze_direction"] is True
    capsys.readouterr()
    with pytest.raises(SystemExit):
        train.main([*args, "--position-from", str(run / "checkpoint.pt")])
    assert "nothing would train" in capsys.readouterr().err


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
