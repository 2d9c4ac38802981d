"""Learner throughput: samples per second of the real training update
(`train.losses`, backward, Adam) on a replay buffer filled with synthetic
observations of the preset's shape, for each way of running it.

    python -m umpnet_train.bench_learner --preset cpu-small --dense-labels 16 --modes fp32,channels-last,bf16

A sample is one image through an encoder (position, executed direction and
dense states), so the figure is comparable across recipes. Collection is not
measured here: `train` reports it as the simulation share.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np
import torch

from .collect import set_device
from .config import make_config
from .models import OBS_MEAN, OBS_STD, UMPNet
from .replay import DenseReplay, Replay
from .train import LEARNER_MODES, Learner

FILL = 512  # samples in each buffer: enough for balanced batches of any preset


def synthetic_replay(cfg, rng: np.random.Generator):
    """Buffers of the preset's shapes, with observations around the networks'
    normalisation statistics and every label class present."""
    shape = (cfg.height, cfg.width, 10)
    fields = cfg.aux_fields > 0
    replay = Replay(FILL, shape, fields=fields)
    dense = DenseReplay(FILL, shape, cfg.dense_labels) if cfg.dense_labels else None

    def image():
        return (np.asarray(OBS_MEAN) + np.asarray(OBS_STD) * rng.standard_normal(shape)).astype(np.float16)

    def flow():
        f = rng.standard_normal((cfg.height, cfg.width, 3))
        return (f / np.linalg.norm(f, axis=-1, keepdims=True)).astype(np.float16)

    pixel = np.array([cfg.height // 2, cfg.width // 2])
    for i in range(FILL // 8):
        ref = replay.add_reference(image())
        for j in range(8):
            replay.add_position(image(), pixel, (i + j) % 2, flow() if fields else None)
            d = rng.standard_normal(3)
            replay.add_direction(
                image(), pixel, d / np.linalg.norm(d), 0.05 * j, j % 3 - 1, ref, flow() if fields else None
            )
        if dense is not None:
            k = cfg.dense_labels
            dirs = rng.standard_normal((k, 3))
            dense.add(image(), pixel, dirs, rng.random(k) * 0.1, rng.integers(-1, 2, k), ref)
    return replay, dense


def samples_per_update(cfg) -> int:
    return cfg.batch_position + cfg.batch_direction + (cfg.dense_states if cfg.dense_labels else 0)


def measure(cfg, mode: str, updates: int, warmup: int, repeats: int) -> dict:
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    replay, dense = synthetic_replay(cfg, rng)
    model = UMPNet(cfg)
    learner = Learner(model, cfg, mode)
    t0 = time.perf_counter()
    for _ in range(warmup):
        learner.update(replay, dense, rng)
    warm_s = time.perf_counter() - t0
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(updates):
            loss = learner.update(replay, dense, rng)
        rates.append(updates * samples_per_update(cfg) / (time.perf_counter() - t0))
    return {
        "mode": mode,
        "samples_per_s": statistics.median(rates),
        "min": min(rates),
        "max": max(rates),
        "ms_per_update": 1e3 * samples_per_update(cfg) / statistics.median(rates),
        "warmup_s": warm_s,
        "final_loss": float(loss["loss/total"]),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--preset", default="cpu-small")
    p.add_argument("--dense-labels", type=int, default=16)
    p.add_argument("--aux-fields", type=float, default=0.0)
    p.add_argument("--direction-widths", help="e.g. 16,32,64 (wider networks)")
    p.add_argument("--position-widths", help="e.g. 16,32,64")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--modes", default=",".join(LEARNER_MODES), help=f"comma-separated, of {', '.join(LEARNER_MODES)}")
    p.add_argument("--updates", type=int, default=20, help="updates per timed repeat")
    p.add_argument("--warmup", type=int, default=5, help="untimed updates first (compilation happens here)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    modes = [m for m in a.modes.split(",") if m]
    bad = [m for m in modes if m not in LEARNER_MODES]
    if bad:
        p.error(f"--modes: unknown {bad}; expected some of {list(LEARNER_MODES)}")
    if min(a.updates, a.repeats) < 1 or a.warmup < 0 or a.threads < 1:
        p.error("--updates and --repeats from 1, --warmup from 0, --threads from 1")

    def widths(text):
        return None if text is None else tuple(int(x) for x in text.split(","))

    cfg = make_config(
        a.preset,
        dense_labels=a.dense_labels,
        aux_fields=a.aux_fields,
        direction_widths=widths(a.direction_widths),
        position_widths=widths(a.position_widths),
        device="cpu",
    )
    torch.set_num_threads(a.threads)
    set_device(torch.device("cpu"))
    rows = [measure(cfg, m, a.updates, a.warmup, a.repeats) for m in modes]
    base = rows[0]["samples_per_s"]
    if a.json:
        print(json.dumps({"preset": a.preset, "threads": a.threads, "torch": torch.__version__, "rows": rows}))
        return 0
    print(
        f"{a.preset} {cfg.height}x{cfg.width}, direction widths {cfg.direction_widths}, dense labels "
        f"{cfg.dense_labels}, aux fields {cfg.aux_fields}, {a.threads} threads, torch {torch.__version__}"
    )
    print(f"{'mode':<16}{'samples/s':>11}{'range':>17}{'ms/update':>11}{'vs first':>10}{'warm-up s':>11}")
    for r in rows:
        print(
            f"{r['mode']:<16}{r['samples_per_s']:>11.1f}{r['min']:>8.1f}-{r['max']:<8.1f}{r['ms_per_update']:>11.1f}"
            f"{r['samples_per_s'] / base:>9.2f}x{r['warmup_s']:>11.1f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
