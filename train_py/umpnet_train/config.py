"""Training configuration: a dataclass with the paper's defaults, and presets."""

from __future__ import annotations

import dataclasses
import difflib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

# The closed sets a field may take, checked by make_config and offered as
# the command line's choices.
VARIANTS = ("umpnet", "single-step", "aot-only", "signed-dist", "where2act", "inverse")
LEARNER_MODES = ("fp32", "channels-last", "bf16", "compile")


def option(default, help: str, choices: tuple | None = None, cli: bool = True, **kw):
    """A Config field with its command-line help (and closed set of choices):
    `train` builds one flag per field from these, so a field is declared once."""
    meta = {"help": help, "choices": choices, "cli": cli}
    return field(default=default, metadata=meta, **kw)


@dataclass
class Config:
    # Observation and networks
    height: int = option(480, "observation height (the paper's 480)")
    width: int = option(640, "observation width (the paper's 640)")
    position_widths: tuple[int, ...] = option((32, 64, 128, 256), "PositionNet U-Net widths per level")
    direction_widths: tuple[int, ...] = option(
        (32, 64, 128, 256), "DirectionNet U-Net widths per level, e.g. 8,16,32,64"
    )
    embedding: int = option(64, "width of the direction encoder's per-pixel embedding")
    action_embedding: int = option(32, "width of the encoded candidate direction")
    direction_net: str = option(
        "context",
        "paper: the paper's DirectionNet (whole-image conv towers, 1024-wide decoders; the paper "
        "preset's); context: a U-Net embedding at the grasp pixel with difference channels, global "
        "context and bilinear heads (models.py); plain: the network of the packages shipped before it",
        choices=("context", "plain", "paper"),
    )
    paper_widths: tuple[int, ...] = option(
        (32, 64, 128, 256, 512, 512, 512),
        "the paper DirectionNet's stages: full resolution, then one halving per further width",
    )
    decoder_hidden: int = option(1024, "width of the decoder MLPs (the paper's appendix)")
    variant: str = option("umpnet", "the method: UMPNet or one of the paper's baselines", choices=VARIANTS)
    # Data collection (the released code: 16 environments, 6400-sample FIFO replay buffer)
    num_envs: int = option(16, "environments collecting in parallel (the released code's 16)")
    replay_size: int = option(6400, "samples in each FIFO replay buffer (the released code's 6400)")
    categories: list[str] = field(
        default_factory=list,
        metadata={"help": "categories to train on (empty: the 12 training categories)", "choices": None, "cli": False},
    )
    physics: str = option(
        "reference",
        "physics profile of the environments: reference (the paper's simulator) or ideal "
        "(every pull follows the joint's path)",
        choices=("reference", "ideal"),
    )
    glass_depth_mix: float = option(
        0.0,
        "share of the environments whose depth camera misreads glass, half reading through it and "
        "half reading nothing there (--glass-depth through and missing), beyond the paper (0: all "
        "read the pane itself)",
    )
    labels: str = option(
        "reference",
        "reference: the released code's label thresholds (0.1 rad / 0.05 m, range/3.5) and its "
        "contradictory policy that turns back at the joint limit; delta: δ thresholds and a turn at half "
        "the sequence (the packages shipped before)",
        choices=("reference", "delta"),
    )
    dense_labels: int = option(
        0,
        "also simulate K directions at every visited state (half the policy's best candidates, half "
        "uniform) and train the decoder on all of them (0: off, the paper)",
    )
    dense_states: int = option(8, "states per dense batch (all their labels in one encoder pass)")
    aux_fields: float = option(
        0.0,
        "weight of the auxiliary articulation-flow losses (FlowBot3D's flow, beyond the paper): the "
        "position net learns each pixel's flow and movable mask, the direction encoder's embedding the "
        "flow (0: off, the paper)",
    )
    aux_flow: str = option(
        "unit",
        "with --aux-fields: the flow target, unit (each point's direction of motion) or scaled (times "
        "its speed relative to its part's fastest point: FlowBot3D's normalised flow, from which one "
        "frame locates a hinge; the position net's head learns it with a squared error)",
        choices=("unit", "scaled"),
    )
    mirror: float = option(
        0.0,
        "share of every batch's states shown mirrored left-right (images' columns reversed, the world's "
        "x negated in points, normals, directions and flow fields; labels kept, since the benchmark "
        "camera sits in the plane x = 0), beyond the paper (0: off)",
    )
    inverse_data: str = option(
        "",
        "variant inverse: a model package whose policy makes the collected moves (epsilon-greedy, "
        "toward the contradictory policy's wanted direction), as the paper trains Inverse on the "
        "policy's own data; empty: uniformly random moves",
    )
    random_grasp: str = option(
        "released",
        "exploratory grasps: released (a uniform pixel, kept above the floor or with probability 0.1, "
        "as the released code) or object (a uniform object pixel, so every grasp can move something)",
        choices=("released", "object"),
    )
    freeze_position: bool = option(
        False,
        "the position net is not trained: its weights come from another run (train --position-from)",
        cli=False,
    )
    freeze_direction: bool = option(
        False,
        "the direction nets are not trained, only the position net (a fine-tune of the grasp, e.g. for "
        "a new sensor); collection still runs them to label the grasps, beyond the paper",
    )
    # Epsilon-greedy schedules: random actions (and no training of that network)
    # until `*_start_epoch`, then a linear decay over `*_decay_epochs`.
    position_epsilon: tuple[float, float] = option((1.0, 0.1), "position epsilon: start,end")
    position_start_epoch: int = option(500, "epoch the position net starts to act and learn")
    position_decay_epochs: int = option(300, "epochs of the position epsilon's decay")
    direction_epsilon: tuple[float, float] = option((1.0, 0.2), "direction epsilon: start,end")
    direction_start_epoch: int = option(800, "epoch the direction nets start to act and learn")
    direction_decay_epochs: int = option(500, "epochs of the direction epsilon's decay")
    # Sequence-length curriculum
    seq_start: int = option(4, "sequence length at the start of the curriculum")
    seq_step: int = option(2, "sequence length added at each curriculum step")
    seq_every: int = option(400, "epochs between curriculum steps")
    seq_after: int = option(1000, "epoch of the first curriculum step")
    seq_max: int = option(20, "longest sequence")
    # Optimisation
    epochs: int = option(5000, "epochs to train")
    batch_position: int = option(16, "position batch, balanced 1:1 positive/negative")
    batch_direction: int = option(24, "direction batch, balanced 1:1:1 over AoT classes")
    iterations_per_epoch: int = option(8, "updates per epoch")
    lr: float = option(8e-3, "learning rate")
    adam_betas: tuple[float, float] = option((0.9, 0.95), "Adam's betas: b1,b2")
    lr_decay_every: int = option(500, "epochs between learning-rate decays")
    lr_decay: float = option(0.5, "learning-rate factor at each decay")
    dist_loss_weight: float = option(100.0, "weight of the distance loss against the AoT loss")
    # Bookkeeping
    seed: int = option(0, "seed of every random choice of the run")
    checkpoint_every: int = option(50, "epochs between checkpoints")
    save_replay: bool = option(
        False,
        "write the replay buffer beside each checkpoint (large: 6400 images per ring), so --resume "
        "continues on the same data",
    )
    eval_every: int = option(0, "epochs between `umpnet eval` runs (0: never)")
    eval_episodes: int = option(5, "episodes per category in `umpnet eval`; twice as many per split in the diagnostics")
    threads: int = option(2, "CPU threads for PyTorch and the environments")
    renderer: str = option("auto", "renderer of the environments", choices=("auto", "wgpu", "cpu"))
    device: str = option("auto", "auto (cuda when available), cpu or cuda")
    learner: str = option(
        "fp32",
        "how updates run: fp32 (the fastest on a CPU without AMX, see bench_learner), channels-last, "
        "bf16 autocast, compile; weights and checkpoints are fp32 whatever the mode",
        choices=LEARNER_MODES,
    )


PRESETS = {
    # The paper's networks: DirectionNet features of 256, action encoders of
    # 128 (its released model.py).
    "paper": {"direction_net": "paper", "embedding": 256, "action_embedding": 128},
    "cpu-small": {
        "height": 96,
        "width": 128,
        "position_widths": (8, 16, 32),
        "direction_widths": (8, 16, 32),
        "embedding": 32,
        "action_embedding": 16,
        "decoder_hidden": 64,
        "num_envs": 16,
        "replay_size": 6400,
        "epochs": 300,
        "position_start_epoch": 0,
        "position_decay_epochs": 200,
        "direction_start_epoch": 0,
        "direction_decay_epochs": 300,
        "seq_start": 4,
        "seq_every": 100,
        "seq_after": 150,
        "seq_max": 8,
        "lr": 1e-3,
        "adam_betas": (0.9, 0.999),
        "lr_decay_every": 250,
        "iterations_per_epoch": 4,
        "checkpoint_every": 50,
    },
    "smoke": {
        "random_grasp": "object",
        "height": 48,
        "width": 64,
        "position_widths": (8, 16),
        "direction_widths": (8, 16),
        "embedding": 16,
        "action_embedding": 8,
        "decoder_hidden": 32,
        "num_envs": 4,
        "replay_size": 256,
        "epochs": 3,
        "position_start_epoch": 0,
        "direction_start_epoch": 0,
        "seq_start": 3,
        "seq_max": 3,
        "iterations_per_epoch": 2,
        "lr": 1e-3,
        "checkpoint_every": 1,
        "eval_episodes": 1,
    },
}
# cpu-small's schedule and position net with wider direction networks,
# twice the environments and four times the updates per epoch: for a lent
# GPU (scripts/device_train.sh), where the learner costs little.
PRESETS["gpu-medium"] = {
    **PRESETS["cpu-small"],
    "direction_widths": (16, 32, 64, 128),
    "embedding": 64,
    "action_embedding": 32,
    "decoder_hidden": 256,
    "num_envs": 32,
    "replay_size": 12800,
    "epochs": 600,
    "iterations_per_epoch": 16,
    "batch_direction": 48,
    "dense_states": 16,
    "checkpoint_every": 25,
}


def make_config(preset: str = "paper", **overrides) -> Config:
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; expected one of {sorted(PRESETS)}")
    values = {**PRESETS[preset], **{k: v for k, v in overrides.items() if v is not None}}
    names = {f.name for f in dataclasses.fields(Config)}
    unknown = set(values) - names
    if unknown:
        raise ValueError(f"unknown config fields {sorted(unknown)}")
    for f in dataclasses.fields(Config):
        choices = f.metadata.get("choices")
        if choices and f.name in values and values[f.name] not in choices:
            expected = ", ".join(repr(c) for c in choices)
            raise ValueError(f"{f.name} {values[f.name]!r}: expected one of {expected}")
    for share in ("mirror", "glass_depth_mix"):
        if not 0.0 <= float(values.get(share, 0.0)) <= 1.0:
            raise ValueError(f"{share} {values[share]}: expected a share between 0 and 1")
    if values.get("freeze_position") and values.get("freeze_direction"):
        raise ValueError("freeze_direction with a frozen position net (--position-from): nothing would train")
    if values.get("inverse_data") and values.get("variant", "umpnet") != "inverse":
        raise ValueError("inverse_data: only the inverse variant collects with another policy's moves")
    cfg_net = values.get("direction_net", "context")
    if cfg_net == "paper":
        widths = values.get("paper_widths", (32, 64, 128, 256, 512, 512, 512))
        h, w = values.get("height", 480), values.get("width", 640)
        if not widths or (h >> (len(widths) - 1)) < 1 or (w >> (len(widths) - 1)) < 1:
            raise ValueError(
                f"paper_widths {tuple(widths)}: {len(widths)} stages halve a {h}x{w} image below one pixel; "
                "give fewer widths (e.g. 8,16,32,64)"
            )
        if values.get("aux_fields", 0.0) > 0:
            raise ValueError("aux_fields: the paper's DirectionNet has no per-pixel embedding to supervise")
    if values.get("dense_labels", 0) < 0:
        raise ValueError(f"dense_labels {values['dense_labels']}: expected 0 (off) or a positive count")
    return Config(**values)


def glass_depths(num_envs: int, mix: float) -> list[str]:
    """Each environment's glass reading for `glass_depth_mix`: the first
    round(mix * num_envs) alternate through and missing, the rest surface."""
    misread = round(mix * num_envs)
    return [("through", "missing")[i % 2] if i < misread else "surface" for i in range(num_envs)]


# What a checkpoint written before a field existed was trained with.
_BEFORE_FIELDS = {
    "direction_net": "plain",
    "decoder_hidden": 64,
    "labels": "delta",
    "position_start_epoch": 0,
    "direction_start_epoch": 0,
    "adam_betas": (0.9, 0.999),
    "random_grasp": "object",
}


def config_from_checkpoint(saved: dict) -> Config:
    """The Config a checkpoint or a package's model.json recorded. JSON turns
    tuples into lists; fields a checkpoint predates take the values it was
    trained with (_BEFORE_FIELDS), not today's defaults."""
    tuples = {f.name for f in dataclasses.fields(Config) if isinstance(f.default, tuple)}
    values = {k: tuple(v) if k in tuples and isinstance(v, list) else v for k, v in saved.items()}
    return Config(**{**_BEFORE_FIELDS, **values})


def read_config_file(path) -> dict:
    """The Config fields (and optionally `preset`) a TOML or JSON file sets; a
    model package's model.json, or a run's config.json, gives the config it
    recorded. Every error names the file and the field."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"--config {path}: cannot read it ({getattr(e, 'strerror', None) or e})") from e
    try:
        if path.suffix == ".toml":
            import tomllib

            data = tomllib.loads(text)
        else:
            data = json.loads(text)
    except ValueError as e:  # tomllib.TOMLDecodeError and json.JSONDecodeError are ValueErrors
        kind = "TOML" if path.suffix == ".toml" else "JSON (a .toml name reads TOML)"
        raise ValueError(f"--config {path}: not valid {kind}: {e}") from e
    if isinstance(data, dict) and data.get("format") == "umpnet-model":
        data = data.get("config")
    if not isinstance(data, dict):
        # A file's content, not a caller's type: the usage error every config mistake is.
        raise ValueError(f"--config {path}: expected a table of config fields, e.g. epochs = 300")  # noqa: TRY004
    fields = {f.name: f for f in dataclasses.fields(Config)}
    values = {}
    for name, value in data.items():
        if name == "preset":
            if value not in PRESETS:
                raise ValueError(f"--config {path}: preset {value!r}: expected one of {sorted(PRESETS)}")
            values[name] = value
            continue
        if name not in fields:
            close = difflib.get_close_matches(name, list(fields) + ["preset"], n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"--config {path}: unknown field {name!r}{hint}")
        values[name] = _typed(path, fields[name], value)
    return values


def _typed(path, f, value):
    """A file's value as the field's type, or a ValueError naming both."""
    kind = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))

    def number(v, item):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return None
        if item is int:
            return v if isinstance(v, int) else None
        return float(v) if math.isfinite(v) else None

    if kind == "bool":
        ok = value if isinstance(value, bool) else None
    elif kind == "list[str]":
        ok = value if isinstance(value, list) and all(isinstance(v, str) for v in value) else None
    elif kind.startswith("tuple"):
        item = float if "float" in kind else int
        size = None if "..." in kind else kind.count(",") + 1
        items = [number(v, item) for v in value] if isinstance(value, list) else [None]
        ok = tuple(items) if items and None not in items and size in (None, len(items)) else None
    elif kind in ("int", "float"):
        ok = number(value, int if kind == "int" else float)
    else:
        ok = value if isinstance(value, str) else None
    if ok is None:
        expected = kind
        if kind.startswith(("tuple", "list")):
            item = "float" if "float" in kind else "int" if "int" in kind else "string"
            size = "" if "..." in kind or kind.startswith("list") else f"{kind.count(',') + 1} "
            expected = f"a list of {size}{item}s"
        raise ValueError(f"--config {path}: {f.name} {value!r}: expected {expected}")
    return ok


def add_config_arguments(parser) -> None:
    """One flag per Config field (`--num-envs` for num_envs), with the field's
    help and choices. Unset flags stay None, so the preset's values hold."""
    for f in dataclasses.fields(Config):
        if not f.metadata.get("cli", True):
            continue
        flag = "--" + f.name.replace("_", "-")
        kind = f.type if isinstance(f.type, str) else getattr(f.type, "__name__", str(f.type))
        common = {"help": f.metadata.get("help"), "default": None}
        if kind == "bool":
            parser.add_argument(flag, action="store_const", const=True, **common)
        elif kind.startswith("tuple"):
            item = float if "float" in kind else int
            size = None if "..." in kind else kind.count(",") + 1
            metavar = "A,B,.." if size is None else ",".join("AB"[:size])
            parser.add_argument(flag, type=_tuple_of(item, f.name, size), metavar=metavar, **common)
        else:
            parser.add_argument(
                flag, type={"int": int, "float": float}.get(kind, str), choices=f.metadata.get("choices"), **common
            )


def config_overrides(namespace) -> dict:
    """The Config fields a parsed command line set."""
    names = {f.name for f in dataclasses.fields(Config)}
    return {k: v for k, v in vars(namespace).items() if k in names and v is not None}


def _tuple_of(item, name, size=None):
    """Comma-separated numbers: positive integers (widths), or non-negative
    reals (epsilons, betas); `size` of them when the field's tuple is fixed."""

    def parse(text):
        try:
            values = tuple(item(x) for x in text.split(","))
        except ValueError:
            values = ()
        positive = item is int
        ok = values and (min(values) > 0 if positive else min(values) >= 0) and size in (None, len(values))
        if not ok:
            import argparse

            what = "positive integers" if positive else "non-negative numbers"
            count = f"{size} " if size else ""
            raise argparse.ArgumentTypeError(
                f"{name} {text!r}: expected {count}{what} separated by commas, e.g. {'8,16,32' if positive else '0.9,0.999'}"
            )
        return values

    parse.__name__ = f"{item.__name__} list"
    return parse
