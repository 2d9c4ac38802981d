"""Collection on Ray actors (`train --ray N`): each actor owns a Rust VecEnv
(and its dense-label probe) and a CPU copy of the networks; every epoch the
learner sends its weights, each actor runs the same `collect` as a local run
on its share of the environments, and returns what it would have added to
the replay buffers. The learner adds the actors' records in actor order, so a
run depends on its seed and actor count, never on which actor finished first.

Seeds: actor a of a run (seed s, started at epoch e) seeds its environments
and its numpy generator from SeedSequence([s, e, a]).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from .config import Config, glass_depths

_NEW_STATS = {
    "sim_s": 0.0, "probe_s": 0.0, "positions": 0, "position_success": 0, "steps": 0,
    "dense_labels": 0, "aot_counts": [0, 0, 0],
}  # fmt: skip


def new_stats() -> dict:
    return {k: list(v) if isinstance(v, list) else v for k, v in _NEW_STATS.items()}


class Recorder:
    """The replay buffers' `add_*` calls (Replay and DenseReplay), recorded in
    order with compact images, to be replayed into the learner's buffers."""

    def __init__(self):
        self.ops: list[tuple] = []
        self.references = 0

    # Replay's interface.
    def add_reference(self, image):
        self.ops.append(("ref", np.asarray(image, np.float16)))
        self.references += 1
        return self.references - 1

    # `flow` is always None here: training refuses --aux-fields with --ray.
    def add_direction(self, image, pixel, direction, r_dist, aot, ref, flow=None):
        self.ops.append(("dir", np.asarray(image, np.float16), pixel, direction, r_dist, aot, ref))

    def add_position(self, image, pixel, label, flow=None):
        self.ops.append(("pos", np.asarray(image, np.float16), pixel, label))

    # DenseReplay's interface.
    def add(self, image, pixel, directions, r_dist, aot, ref):
        self.ops.append(("dense", np.asarray(image, np.float16), pixel, directions, r_dist, aot, ref))


def replay_into(ops: list[tuple], replay, dense) -> None:
    """Adds recorded operations to the learner's buffers; a recorded
    reference index becomes the slot the reference got here."""
    slots = []
    for op in ops:
        kind, rest = op[0], op[1:]
        if kind == "ref":
            slots.append(replay.add_reference(rest[0]))
        elif kind == "dir":
            replay.add_direction(*rest[:-1], slots[rest[-1]])
        elif kind == "pos":
            replay.add_position(*rest)
        elif kind == "dense" and dense is not None:
            dense.add(*rest[:-1], slots[rest[-1]])


def merge_stats(total: dict, part: dict) -> None:
    for k, v in part.items():
        if isinstance(v, list):
            total[k] = [a + b for a, b in zip(total[k], v, strict=True)]
        else:
            total[k] += v


def split_envs(num_envs: int, actors: int) -> list[int]:
    """Environments per actor: the run's total, spread as evenly as it goes."""
    if actors < 1 or actors > num_envs:
        raise ValueError(f"--ray {actors}: expected 1 to num_envs ({num_envs}) actors")
    return [num_envs // actors + (1 if a < num_envs % actors else 0) for a in range(actors)]


class Collector:
    """One Ray actor's state: environments, a CPU model, its own generator."""

    def __init__(self, cfg_fields: dict, actor: int, num_envs: int, start_epoch: int, categories: list[str]):
        import torch
        import umpnet

        from .models import UMPNet

        torch.set_num_threads(1)
        self.cfg = Config(**cfg_fields)
        seeds = np.random.SeedSequence([self.cfg.seed, start_epoch, actor])
        env_seed, rng_seed = seeds.generate_state(2, np.uint64)
        self.rng = np.random.default_rng(int(rng_seed))
        self.model = UMPNet(self.cfg)
        self.env = umpnet.VecEnv(
            num_envs,
            category=categories,
            split="train",
            seed=int(env_seed),
            resolution=(self.cfg.height, self.cfg.width),
            renderer=self.cfg.renderer,
            physics=self.cfg.physics,
            glass_depths=glass_depths(num_envs, self.cfg.glass_depth_mix),
        )

    def collect(self, weights: dict, epoch: int) -> tuple[list[tuple], dict]:
        from .collect import collect

        self.model.load_state_dict(weights)
        recorder, stats = Recorder(), new_stats()
        dense = recorder if self.cfg.dense_labels else None
        collect(self.env, self.model, self.cfg, recorder, dense, epoch, self.rng, stats)
        return recorder.ops, stats


class RayCollection:
    """The learner's side: starts the actors, runs an epoch's collection on all
    of them, and adds the results to the buffers in actor order."""

    def __init__(self, cfg: Config, actors: int, start_epoch: int, categories: list[str], address: str | None):
        import ray

        self.ray = ray
        if not ray.is_initialized():
            # The package travels with the job (py_modules), so a cluster's
            # workers need umpnet and torch installed, not this source tree.
            job = {"runtime_env": {"py_modules": [str(Path(__file__).resolve().parent)]}, "log_to_driver": False}
            if address:
                ray.init(address=address, **job)
            else:
                ray.init(num_cpus=actors, include_dashboard=False, **job)
        remote = ray.remote(num_cpus=1)(Collector)
        fields = dataclasses.asdict(cfg)
        self.actors = [
            remote.remote(fields, a, n, start_epoch, categories) for a, n in enumerate(split_envs(cfg.num_envs, actors))
        ]

    def collect(self, model, epoch: int, replay, dense, stats: dict) -> None:
        weights = self.ray.put({k: v.detach().cpu() for k, v in model.state_dict().items()})
        parts = self.ray.get([a.collect.remote(weights, epoch) for a in self.actors])
        for ops, part in parts:
            replay_into(ops, replay, dense)
            merge_stats(stats, part)

    def close(self) -> None:
        for a in self.actors:
            self.ray.kill(a)
        self.actors = []
