"""`umpnet_train.interpolate`: the chosen networks lie on the line between a
checkpoint and its fine-tune, the others are the base's, and bad input is
refused without touching what is already written."""

import dataclasses

import pytest
import torch
from umpnet_train import interpolate
from umpnet_train.config import make_config
from umpnet_train.models import UMPNet


def _checkpoint(seed, cfg=None):
    torch.manual_seed(seed)
    cfg = cfg or make_config("smoke")
    model = UMPNet(cfg)
    with torch.no_grad():
        for v in model.state_dict().values():
            if v.is_floating_point():
                v.add_(torch.randn_like(v))  # BatchNorm's running statistics differ too
    return {
        "config": dataclasses.asdict(cfg),
        "model": model.state_dict(),
        "optimizer": {"state": {}},
        "epoch": 10 * seed,
        "provenance": {"command": f"seed {seed}", "segments": [{"from_epoch": 0}]},
    }


@pytest.fixture
def pair(tmp_path):
    base, tuned = _checkpoint(1), _checkpoint(2)
    # A fine-tune of the grasp alone: the direction networks are the base's.
    for k, v in base["model"].items():
        if not k.startswith("position."):
            tuned["model"][k] = v.clone()
    torch.save(base, tmp_path / "base.pt")
    torch.save(tuned, tmp_path / "tuned.pt")
    return tmp_path, base, tuned


@pytest.mark.parametrize("alpha", [0.0, 0.3, 1.0])
def test_the_chosen_net_is_on_the_line_and_the_rest_is_the_base(pair, alpha):
    root, base, tuned = pair
    assert (
        interpolate.main([str(root / "base.pt"), str(root / "tuned.pt"), str(root / "out"), "--alpha", str(alpha)]) == 0
    )
    out = torch.load(root / "out" / "checkpoint.pt", map_location="cpu", weights_only=False)
    for k, v in out["model"].items():
        a, b = base["model"][k], tuned["model"][k]
        if k.startswith("position.") and v.is_floating_point():
            torch.testing.assert_close(v, (1 - alpha) * a + alpha * b)
        else:
            assert torch.equal(v, a), k
    assert "optimizer" not in out  # no training reached this point
    segment = out["provenance"]["segments"][-1]
    assert segment["alpha"] == alpha and segment["nets"] == ["position"]
    assert segment["finetuned"]["epoch"] == 20 and segment["left_out_tensors_that_differ"] == 0
    assert out["provenance"]["segments"][0] == {"from_epoch": 0}  # the base's history is kept
    model = UMPNet(make_config("smoke"))
    model.load_state_dict(out["model"])  # a checkpoint export and train --resume accept


def test_interpolating_every_net_moves_the_direction_nets_too(pair):
    root, base, _ = pair
    other = _checkpoint(3)
    torch.save(other, root / "other.pt")
    args = [str(root / "base.pt"), str(root / "other.pt"), str(root / "out"), "--nets", "position,encoder,decoder"]
    assert interpolate.main(args) == 0
    out = torch.load(root / "out" / "checkpoint.pt", map_location="cpu", weights_only=False)
    k = next(k for k in out["model"] if k.startswith("decoder.") and out["model"][k].is_floating_point())
    torch.testing.assert_close(out["model"][k], 0.5 * base["model"][k] + 0.5 * other["model"][k])


def test_a_different_architecture_is_refused(pair, capsys):
    root, _, _ = pair
    wide = make_config("smoke")
    wide = dataclasses.replace(wide, position_widths=tuple(2 * w for w in wide.position_widths))
    torch.save(_checkpoint(4, wide), root / "wide.pt")
    assert interpolate.main([str(root / "base.pt"), str(root / "wide.pt"), str(root / "out")]) == 2
    assert "different networks" in capsys.readouterr().err
    assert not (root / "out").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [(["--alpha", "1.5"], "between 0 and 1"), (["--nets", "grasp"], "expected some of position")],
)
def test_bad_settings_are_named(pair, capsys, extra, message):
    root, _, _ = pair
    assert interpolate.main([str(root / "base.pt"), str(root / "tuned.pt"), str(root / "out"), *extra]) == 2
    assert message in capsys.readouterr().err


def test_an_existing_checkpoint_is_kept_without_force(pair, capsys):
    root, _, _ = pair
    (root / "out").mkdir()
    (root / "out" / "checkpoint.pt").write_bytes(b"earlier run")
    assert interpolate.main([str(root / "base.pt"), str(root / "tuned.pt"), str(root / "out")]) == 2
    assert "--force" in capsys.readouterr().err
    assert (root / "out" / "checkpoint.pt").read_bytes() == b"earlier run"
    assert interpolate.main([str(root / "base.pt"), str(root / "missing.pt"), str(root / "out")]) == 2
    assert "missing.pt: no such checkpoint" in capsys.readouterr().err


def test_a_file_that_is_not_a_checkpoint_is_named(pair, capsys):
    root, _, _ = pair
    (root / "broken.pt").write_bytes((root / "tuned.pt").read_bytes()[:100])  # a truncated copy
    assert interpolate.main([str(root / "base.pt"), str(root / "broken.pt"), str(root / "out")]) == 2
    assert "broken.pt: not a readable checkpoint" in capsys.readouterr().err
    torch.save({"weights": {}}, root / "foreign.pt")
    assert interpolate.main([str(root / "foreign.pt"), str(root / "tuned.pt"), str(root / "out")]) == 2
    assert "foreign.pt: not a umpnet_train checkpoint" in capsys.readouterr().err
    assert not (root / "out").exists()
