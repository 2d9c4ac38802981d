"""Training configuration: a dataclass with the paper's defaults, and presets."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field


@dataclass
class Config:
    # Observation and networks
    height: int = 480
    width: int = 640
    position_widths: tuple[int, ...] = (32, 64, 128, 256)
    direction_widths: tuple[int, ...] = (32, 64, 128, 256)
    embedding: int = 64
    action_embedding: int = 32
    # "context": difference channels, global context, bilinear heads (models.py);
    # "plain": the direction network of the packages shipped before it.
    direction_net: str = "context"
    decoder_hidden: int = 1024  # width of the decoder MLPs (the paper's appendix)
    variant: str = "umpnet"  # umpnet | single-step | aot-only | signed-dist | where2act | inverse
    # Data collection (the released code: 16 environments, 6400-sample FIFO replay buffer)
    num_envs: int = 16
    replay_size: int = 6400
    categories: list[str] = field(default_factory=list)  # empty: the 12 training categories
    physics: str = "reference"  # the paper's simulator; "ideal": every pull follows the joint's path
    # "reference": the released code's thresholds (0.1 rad / 0.05 m, range/3.5) and a
    # contradictory policy that turns back at the joint limit; "delta": δ thresholds and
    # a turn at half the sequence (the packages shipped before).
    labels: str = "reference"
    # Dense labels: at each visited state also simulate this many directions (half the
    # policy's best candidates, half uniform) and train the decoder on all of them.
    # 0: only the executed action, as the paper.
    dense_labels: int = 0
    dense_states: int = 8  # states per dense batch (all their labels in one encoder pass)
    # Dense articulation supervision (beyond the paper; FlowBot3D's articulation flow):
    # weight of the auxiliary losses that teach the position net each pixel's flow and
    # movable mask, and the direction encoder's per-pixel embedding the flow. 0: off.
    aux_fields: float = 0.0
    # Exploratory grasps: "released" (the released code's rule: a uniform pixel,
    # kept above the floor or with probability 0.1) or "object" (a uniform
    # object pixel: every grasp can move something; the smoke preset's, whose
    # two epochs must collect moves).
    random_grasp: str = "released"
    # The position net is not trained: its weights come from another run's checkpoint
    # (train --position-from), and the direction nets learn from that net's grasps.
    freeze_position: bool = False
    # Epsilon-greedy schedules: random actions (and no training of that network)
    # until `*_start_epoch`, then a linear decay over `*_decay_epochs`.
    position_epsilon: tuple[float, float] = (1.0, 0.1)
    position_start_epoch: int = 500
    position_decay_epochs: int = 300
    direction_epsilon: tuple[float, float] = (1.0, 0.2)
    direction_start_epoch: int = 800
    direction_decay_epochs: int = 500
    # Sequence-length curriculum: start, step, every, after, max
    seq_start: int = 4
    seq_step: int = 2
    seq_every: int = 400
    seq_after: int = 1000
    seq_max: int = 20
    # Optimisation
    epochs: int = 5000
    batch_position: int = 16  # balanced 1:1 positive/negative
    batch_direction: int = 24  # balanced 1:1:1 over AoT classes
    iterations_per_epoch: int = 8
    lr: float = 8e-3
    adam_betas: tuple[float, float] = (0.9, 0.95)
    lr_decay_every: int = 500
    lr_decay: float = 0.5
    dist_loss_weight: float = 100.0
    # Bookkeeping
    seed: int = 0
    checkpoint_every: int = 50
    save_replay: bool = False  # also write OUT/replay.npz at checkpoints (large: 6400 images per ring)
    eval_every: int = 0
    eval_episodes: int = 5  # per category in `umpnet eval`; twice as many per split in the diagnostics
    threads: int = 2
    renderer: str = "auto"
    device: str = "auto"  # auto (cuda when available), cpu, cuda
    # How updates run (train.LEARNER_MODES): fp32, channels-last, bf16, compile.
    # Weights and checkpoints are fp32 whatever the mode.
    learner: str = "fp32"


PRESETS = {
    "paper": {},
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


def make_config(preset: str = "paper", **overrides) -> Config:
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r}; expected one of {sorted(PRESETS)}")
    values = {**PRESETS[preset], **{k: v for k, v in overrides.items() if v is not None}}
    names = {f.name for f in dataclasses.fields(Config)}
    unknown = set(values) - names
    if unknown:
        raise ValueError(f"unknown config fields {sorted(unknown)}")
    if values.get("random_grasp", "released") not in ("released", "object"):
        raise ValueError(f"random_grasp {values['random_grasp']!r}: expected 'released' or 'object'")
    if values.get("direction_net", "context") not in ("context", "plain"):
        raise ValueError(f"direction_net {values['direction_net']!r}: expected 'context' or 'plain'")
    if values.get("labels", "reference") not in ("reference", "delta"):
        raise ValueError(f"labels {values['labels']!r}: expected 'reference' or 'delta'")
    if values.get("learner", "fp32") not in ("fp32", "channels-last", "bf16", "compile"):
        raise ValueError(f"learner {values['learner']!r}: expected fp32, channels-last, bf16 or compile")
    if values.get("dense_labels", 0) < 0:
        raise ValueError(f"dense_labels {values['dense_labels']}: expected 0 (off) or a positive count")
    return Config(**values)


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
