"""The training command line: the presets, the flags generated from Config,
config files between the preset and the flags, and the schedules a config
sets."""

import dataclasses
import json
from pathlib import Path

import pytest
from umpnet_train import collect, train
from umpnet_train.config import Config, config_from_checkpoint, make_config

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
