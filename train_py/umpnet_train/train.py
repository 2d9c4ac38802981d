"""Train UMPNet against the umpnet Rust environments, the paper's way:
self-guided exploration with epsilon-greedy position/direction choices after
a random warm-up, the contradictory policy (forward until the joint limit or
half the sequence, then back to the start), the released code's label
thresholds, a growing sequence length, FIFO replay, balanced batches, and the
loss 100 x MSE(distance) + CE(AoT) (+ CE(position)). With --dense-labels K the
simulator also labels K directions at every visited state (the policy's best
candidates and random ones), and the decoder trains on all of them. With
--mirror P a share P of every batch's states is shown mirrored left-right
(beyond the paper; mirror.py).
How the data is gathered lives in collect.py; this file learns from it.

    python -m umpnet_train.train --preset cpu-small --out ../runs/small --export ../runs/small-package
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pickle
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
import umpnet
from torch.utils.tensorboard import SummaryWriter
from tqdm import tqdm

from . import mirror
from .collect import TRAIN_CATEGORIES, collect, device, sequence_length, set_device, to_long, to_torch
from .config import (
    LEARNER_MODES,
    add_config_arguments,
    config_from_checkpoint,
    config_overrides,
    glass_depths,
    make_config,
    read_config_file,
)
from .export import export_model
from .models import UMPNet, UNet
from .replay import DenseReplay, Replay


def class_weights(groups: torch.Tensor, classes: int) -> torch.Tensor:
    """Per-sample weights that give each class present the same total weight
    (summing to 1): a dense batch balanced the way the executed batches are
    sampled (1:1:1 over AoT classes)."""
    counts = torch.bincount(groups, minlength=classes).float()
    present = (counts > 0).sum()
    return (1.0 / counts.clamp(min=1))[groups] / present


def direction_losses(cfg, pred_dist, logits, dist, aot, weights, prefix, out):
    """The direction network's loss for one batch (executed or dense), by
    variant; `weights` sum to 1 over the batch. Returns the weighted total."""

    def mean(x):
        return (x * weights).sum()

    aot_t = to_long(aot + 1)
    if cfg.variant == "where2act":
        moved = to_torch((aot != 0).astype(np.float32))
        out[f"loss/{prefix}success"] = mean(F.binary_cross_entropy_with_logits(pred_dist, moved, reduction="none"))
        out[f"metric/{prefix}success_accuracy"] = ((pred_dist > 0).float() == moved).float().mean()
        return out[f"loss/{prefix}success"]
    if cfg.variant == "signed-dist":
        out[f"loss/{prefix}dist"] = mean((pred_dist - to_torch(dist * aot.astype(np.float32))) ** 2)
        return cfg.dist_loss_weight * out[f"loss/{prefix}dist"]
    out[f"loss/{prefix}aot"] = mean(F.cross_entropy(logits, aot_t, reduction="none"))
    out[f"metric/{prefix}aot_accuracy"] = (logits.argmax(1) == aot_t).float().mean()
    total = out[f"loss/{prefix}aot"]
    if cfg.variant != "aot-only":
        out[f"loss/{prefix}dist"] = mean((pred_dist - to_torch(dist)) ** 2)
        total = total + cfg.dist_loss_weight * out[f"loss/{prefix}dist"]
    return total


def flow_losses(pred_flow, flow, out, prefix, pred_movable=None, scaled=False):
    """Auxiliary articulation losses on movable pixels: 1 - cosine between
    predicted and true flow (unit flow), or their squared error (scaled flow,
    whose length carries each point's relative speed); and, with
    `pred_movable`, the movable mask (BCE)."""
    target = to_torch(flow).permute(0, 3, 1, 2)  # N x 3 x H x W
    movable = target.norm(dim=1) > 1e-6
    total = torch.zeros((), device=device())
    if movable.any():
        cos = F.cosine_similarity(pred_flow, target, dim=1, eps=1e-6)[movable]
        if scaled:
            out[f"loss/{prefix}flow"] = (pred_flow - target).pow(2).sum(dim=1)[movable].mean()
        else:
            out[f"loss/{prefix}flow"] = (1.0 - cos).mean()
        out[f"metric/{prefix}flow_cosine"] = cos.mean().detach()
        total = total + out[f"loss/{prefix}flow"]
    if pred_movable is not None:
        out[f"loss/{prefix}movable"] = F.binary_cross_entropy_with_logits(pred_movable, movable.float())
        total = total + out[f"loss/{prefix}movable"]
    return total


def losses(model, cfg, replay, dense, rng, train_position=True, train_direction=True):
    out = {}
    total = torch.zeros((), device=device())
    fields = cfg.aux_fields > 0
    imgs, pix, lab, *pos_flow = replay.sample_positions(rng, cfg.batch_position, flows=fields)
    (imgs,), (pix,), _, pos_flow = mirror.states(mirror.chosen(rng, len(lab), cfg.mirror), [imgs], [pix], [], pos_flow)
    if train_position and len(lab) and fields:
        logits, aux = model.position.forward_fields(to_torch(imgs))
        total = total + cfg.aux_fields * flow_losses(
            aux[:, :3], pos_flow[0], out, "position_", aux[:, 3], cfg.aux_flow == "scaled"
        )
    elif train_position and len(lab):
        logits = model.position(to_torch(imgs))
    if train_position and len(lab):
        at = logits[torch.arange(len(lab), device=device()), :, to_long(pix[:, 0]), to_long(pix[:, 1])]
        target = to_long(lab)
        out["loss/position"] = F.cross_entropy(at, target)
        pred = at.argmax(1)
        tp, fp = int(((pred == 1) & (target == 1)).sum()), int(((pred == 1) & (target == 0)).sum())
        out["metric/position_precision"] = torch.tensor(tp / max(tp + fp, 1))
        total = total + out["loss/position"]
    if not train_direction:
        out["loss/total"] = total
        return out
    groups = {"where2act": "binary", "inverse": "moved"}.get(cfg.variant, "aot")
    imgs, refs, pix, dirs, dist, aot, *dir_flow = replay.sample_directions(
        rng, cfg.batch_direction, groups, flows=fields
    )
    (imgs, refs), (pix,), (dirs,), dir_flow = mirror.states(
        mirror.chosen(rng, len(aot), cfg.mirror), [imgs, refs], [pix], [dirs], dir_flow
    )
    if len(aot) and cfg.variant == "inverse":
        pred = model.inverse(to_torch(imgs), to_torch(refs), to_long(pix))
        out["loss/inverse"] = F.mse_loss(pred, to_torch(dirs))
        out["metric/inverse_cosine"] = F.cosine_similarity(pred, to_torch(dirs), dim=1).mean()
        total = total + out["loss/inverse"]
    elif len(aot):
        obs_t, refs_t, pix_t = to_torch(imgs), to_torch(refs), to_long(pix)
        if fields:
            de, ae, pred_flow = model.encoder.forward_fields(obs_t, refs_t, pix_t)
            total = total + cfg.aux_fields * flow_losses(
                pred_flow, dir_flow[0], out, "direction_", scaled=cfg.aux_flow == "scaled"
            )
        else:
            de, ae = model.encoder(obs_t, refs_t, pix_t)
        pred_dist, logits = model.decoder(de, ae, to_torch(dirs))
        weights = torch.full((len(aot),), 1.0 / len(aot), device=device())  # already balanced by sampling
        total = total + direction_losses(cfg, pred_dist, logits, dist, aot, weights, "", out)
    batch = dense.sample(rng, cfg.dense_states, replay.refs, replay.ref_images) if dense is not None else None
    if batch is not None and cfg.variant != "inverse":
        imgs, refs, pix, dirs, dist, aot = batch
        (imgs, refs), (pix,), (dirs,), _ = mirror.states(
            mirror.chosen(rng, len(aot), cfg.mirror), [imgs, refs], [pix], [dirs], []
        )
        k = dirs.shape[1]
        de, ae = model.encoder(to_torch(imgs), to_torch(refs), to_long(pix))
        pred_dist, logits = model.decoder(
            de.repeat_interleave(k, 0), ae.repeat_interleave(k, 0), to_torch(dirs.reshape(-1, 3))
        )
        aot, dist = aot.reshape(-1), dist.reshape(-1)
        groups_t = to_long((aot != 0).astype(np.int64) if cfg.variant == "where2act" else aot + 1)
        weights = class_weights(groups_t, 3)
        total = total + direction_losses(cfg, pred_dist, logits, dist, aot, weights, "dense_", out)
    out["loss/total"] = total
    return out


# How the learner runs its update (bench_learner measures each on this machine):
# fp32 eager; channels-last memory format; bf16 autocast of the forward passes;
# torch.compile of the U-Nets and decoder.


class Learner:
    """The model, its optimiser and one update (losses, backward, Adam step),
    run the way `mode` says. Modes change speed, not what is learned: the
    weights, the optimiser state and the checkpoints are the same fp32 ones."""

    def __init__(self, model: UMPNet, cfg, mode: str = "fp32"):
        if mode not in LEARNER_MODES:
            raise ValueError(f"learner mode {mode!r}: expected one of {list(LEARNER_MODES)}")
        self.model, self.cfg, self.mode = model, cfg, mode
        self.opt = torch.optim.Adam(model.parameters(), lr=cfg.lr, betas=tuple(cfg.adam_betas))
        if mode == "channels-last":
            model.to(memory_format=torch.channels_last)
        if mode == "compile":
            # Bound methods, not modules, are compiled: the state_dict keys stay
            # those of the eager model, so checkpoints and export are unchanged.
            for m in model.modules():
                if isinstance(m, UNet):
                    m.forward_with_features = torch.compile(m.forward_with_features, dynamic=True)
            model.decoder.forward = torch.compile(model.decoder.forward, dynamic=True)

    def update(self, replay, dense, rng, train_position=True, train_direction=True) -> dict:
        """One optimisation step; returns the losses and metrics (detached)."""
        with torch.autocast(device().type, dtype=torch.bfloat16, enabled=self.mode == "bf16"):
            out = losses(self.model, self.cfg, replay, dense, rng, train_position, train_direction)
        if out["loss/total"].requires_grad:  # nothing to train during the warm-up
            self.opt.zero_grad()
            out["loss/total"].float().backward()
            self.opt.step()
        return {k: v.detach().float() for k, v in out.items()}


def load_position(model: UMPNet, widths, path: Path) -> dict:
    """Copy the position net's weights from the checkpoint at `path` into
    `model` and stop their training. Returns where they came from (for the
    provenance)."""
    try:
        ck = torch.load(path, map_location=device(), weights_only=False)
    except FileNotFoundError:
        raise ValueError("no such file") from None
    except (OSError, EOFError, RuntimeError, ValueError, pickle.UnpicklingError) as e:
        raise ValueError(f"cannot be read as a checkpoint ({type(e).__name__}: {e})") from None
    if not isinstance(ck, dict) or "model" not in ck:
        raise ValueError("not a training checkpoint (no 'model' entry)")
    prefix = "position."
    weights = {k[len(prefix) :]: v for k, v in ck["model"].items() if k.startswith(prefix)}
    ours = model.position.state_dict()
    if weights.keys() != ours.keys() or any(weights[k].shape != ours[k].shape for k in ours):
        theirs = ck.get("config", {}).get("position_widths", "unknown")
        raise ValueError(f"its position net (widths {theirs}) does not match this run's ({list(widths)})")
    model.position.load_state_dict(weights)
    model.position.requires_grad_(False)
    prov = ck.get("provenance", {})
    return {
        "checkpoint": str(path),
        "epochs": ck.get("epoch"),
        "command": prov.get("command"),
        "git_commit": prov.get("git_commit"),
    }


def git_commit() -> str:
    """The commit the training code runs from, with "-dirty" when that code
    has uncommitted changes (the commit alone would then not reproduce it)."""
    here = Path(__file__).resolve().parent
    if os.environ.get("UMPNET_GIT_COMMIT"):
        # Named by whoever sent the files (a lent GPU machine's copy can carry
        # a stale .git of its own).
        return os.environ["UMPNET_GIT_COMMIT"]
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, check=True
        ).stdout.strip()
        changed = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", "."],
            cwd=here, capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return f"{head}-dirty" if changed else head


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--preset", help="paper, cpu-small (the default), gpu-medium or smoke")
    p.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="config fields from a TOML or JSON file (a run's config.json, or a package's model.json, "
        "repeats that run): over the preset, under the flags",
    )
    p.add_argument("--out", type=Path, required=True, help="run directory: checkpoints and TensorBoard logs")
    p.add_argument("--export", type=Path, help="write the final model package here")
    p.add_argument("--resume", action="store_true", help="continue from OUT/checkpoint.pt")
    p.add_argument(
        "--restart-lr",
        type=float,
        metavar="LR",
        help="with --resume: set the learning rate to LR from the resumed epoch on (the step decay "
        "continues from there); for fine-tuning after a change to the simulator",
    )
    p.add_argument(
        "--position-from",
        type=Path,
        metavar="CHECKPOINT",
        help="take the position net's weights from CHECKPOINT (same architecture) and do not train it: "
        "the direction nets then learn from that net's grasps; pass it again when resuming",
    )
    # One flag per Config field, with its help and choices (config.py).
    add_config_arguments(p)
    p.add_argument(
        "--ray",
        type=int,
        default=0,
        metavar="N",
        help="collect on N Ray actors (each with its share of the environments); 0: in this process",
    )
    p.add_argument("--ray-address", help="an existing Ray cluster (as for ray.init); default: a local one")
    p.add_argument(
        "--time-limit",
        type=float,
        metavar="SECONDS",
        help="stop after the epoch that passes SECONDS of wall time, with a checkpoint (--resume continues "
        "it) and the export: for a lease that ends (a lent GPU machine, a session); the schedules keep "
        "their epochs, so the run is the same run stopped early",
    )
    a = p.parse_args(argv)
    if a.time_limit is not None and not a.time_limit > 0:
        p.error(f"--time-limit {a.time_limit}: expected a positive number of seconds")
    if a.ray < 0:
        p.error(f"--ray {a.ray}: expected 0 (local collection) or a number of actors")
    if a.aux_fields is not None and not (a.aux_fields >= 0 and a.aux_fields < 1e3):
        p.error(f"--aux-fields {a.aux_fields}: expected a weight in [0, 1000)")
    if a.ray and a.aux_fields:
        p.error("--aux-fields collects the fields in this process: use it without --ray")
    try:
        from_file = read_config_file(a.config) if a.config else {}
        file_preset = from_file.pop("preset", None)
        a.preset = a.preset or file_preset or "cpu-small"
        overrides = {**from_file, **config_overrides(a)}
        if a.position_from is not None:
            overrides["freeze_position"] = True
        cfg = make_config(a.preset, **overrides)
    except ValueError as e:
        p.error(str(e))
    return cfg, a


def evaluate(model, cfg, out: Path, umpnet_bin: str, writer, epoch: int):
    package = out / "eval-package"
    copy = UMPNet(cfg)
    copy.load_state_dict({k: v.cpu() for k, v in model.state_dict().items()})
    export_model(copy, cfg, package, {"note": "periodic evaluation"})
    for task in ["exploration", "goal"]:
        res = subprocess.run(
            [umpnet_bin, "--json", "eval", "--task", task, "--split", "train", "--episodes-per-category", str(cfg.eval_episodes),
             "--policies", f"umpnet={package}", "--physics", cfg.physics],
            capture_output=True, text=True, check=False,
        )  # fmt: skip
        if res.returncode != 0:
            print(f"warning: evaluation failed: {res.stderr.strip()}", file=sys.stderr)
            continue
        cells = json.loads(res.stdout)["cells"]
        for metric in {c["metric"] for c in cells}:
            values = [c["mean"] for c in cells if c["metric"] == metric]
            writer.add_scalar(f"eval/{task}/{metric}", float(np.mean(values)), epoch)
    # The diagnostics (umpnet_train.diagnose) on a few held-out episodes: where the
    # policy loses, as training goes.
    from .diagnose import diagnose

    try:
        report = diagnose(package, episodes=2 * cfg.eval_episodes, seed=cfg.seed, physics=cfg.physics)
    except (ValueError, RuntimeError) as e:
        print(f"warning: diagnostics failed: {e}", file=sys.stderr)
        return
    for split, tasks in report["splits"].items():
        for task in ("exploration", "goal"):
            for key, value in tasks[task].items():
                # Scalars only: the intervals and the AoT confusion are lists.
                if key not in ("episodes", "states", "success") and isinstance(value, (int, float)):
                    writer.add_scalar(f"diagnose/{split}/{task}/{key}", value, epoch)
        for combo, value in tasks["swap"].items():
            if value is not None:
                writer.add_scalar(f"diagnose/{split}/goal_success/{combo}", value, epoch)


def main(argv=None) -> int:
    cfg, args = parse_args(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    # The whole configuration, so that `--config OUT/config.json` repeats the run.
    partial = out / "config.json.partial"
    partial.write_text(json.dumps({"preset": args.preset, **dataclasses.asdict(cfg)}, indent=2) + "\n")
    partial.replace(out / "config.json")
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.threads)
    rng = np.random.default_rng(cfg.seed)
    set_device(
        torch.device(
            "cuda" if cfg.device == "auto" and torch.cuda.is_available() else cfg.device.replace("auto", "cpu")
        )
    )
    model = UMPNet(cfg).to(device())
    learner = Learner(model, cfg, cfg.learner)
    opt = learner.opt
    sched = torch.optim.lr_scheduler.StepLR(opt, step_size=cfg.lr_decay_every, gamma=cfg.lr_decay)
    start, wall_before = 0, 0.0
    segments = []  # each invocation of a run: the epoch it started at and its code's commit
    ckpt_path = out / "checkpoint.pt"
    if args.restart_lr is not None and not (args.resume and 0 < args.restart_lr < 1):
        print(f"error: --restart-lr {args.restart_lr}: needs --resume and a rate in (0, 1)", file=sys.stderr)
        return 2
    if args.resume:
        if not ckpt_path.is_file():
            print(f"error: --resume: {ckpt_path} does not exist", file=sys.stderr)
            return 2
        ck = torch.load(ckpt_path, map_location=device(), weights_only=False)
        saved = config_from_checkpoint(ck["config"])
        if saved.direction_net != cfg.direction_net:
            print(
                f"error: --resume: {ckpt_path} holds a {saved.direction_net!r} direction network; "
                f"add --direction-net {saved.direction_net}",
                file=sys.stderr,
            )
            return 2
        if dataclasses.asdict(saved) != dataclasses.asdict(cfg):
            print("warning: resuming with a configuration different from the checkpoint's", file=sys.stderr)
        model.load_state_dict(ck["model"])
        if "optimizer" in ck:
            opt.load_state_dict(ck["optimizer"])
            sched.load_state_dict(ck["scheduler"])
        else:
            # A fine-tuned checkpoint (umpnet_train.candidates) keeps no Adam
            # state: Adam starts afresh, at the learning rate the schedule has reached.
            sched.last_epoch = ck["epoch"]
            for group in opt.param_groups:
                group["lr"] = cfg.lr * cfg.lr_decay ** (ck["epoch"] // cfg.lr_decay_every)
            print("note: the checkpoint has no optimiser state; Adam starts afresh", file=sys.stderr)
        if args.restart_lr is not None:
            for group in opt.param_groups:
                group["lr"] = args.restart_lr
            print(f"learning rate restarted at {args.restart_lr:g}")
        rng.bit_generator.state = ck["numpy_rng"]
        torch.set_rng_state(ck["torch_rng"])
        start, wall_before = ck["epoch"], ck["provenance"]["wall_seconds"]
        segments = ck["provenance"].get("segments", [])
    position_from = None
    if args.position_from is not None:
        try:
            position_from = load_position(model, cfg.position_widths, args.position_from)
        except ValueError as e:
            print(f"error: --position-from {args.position_from}: {e}", file=sys.stderr)
            return 2
        print(f"position net from {args.position_from} (epoch {position_from.get('epochs')}), not trained")
    categories = cfg.categories or TRAIN_CATEGORIES
    env, collection = None, None
    if args.ray:
        from .distributed import RayCollection, split_envs

        try:
            split_envs(cfg.num_envs, args.ray)
        except ValueError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        collection = RayCollection(cfg, args.ray, start, categories, args.ray_address)
    else:
        env = umpnet.VecEnv(
            cfg.num_envs,
            category=categories,
            split="train",
            seed=cfg.seed * 1000 + start,
            resolution=(cfg.height, cfg.width),
            renderer=cfg.renderer,
            physics=cfg.physics,
            glass_depths=glass_depths(cfg.num_envs, cfg.glass_depth_mix),
        )
    replay = Replay(cfg.replay_size, (cfg.height, cfg.width, 10), fields=cfg.aux_fields > 0)
    # Dense states keep one image for K labels: a quarter of the buffer's states.
    dense = (
        DenseReplay(max(cfg.replay_size // 4, 1), (cfg.height, cfg.width, 10), cfg.dense_labels)
        if cfg.dense_labels
        else None
    )
    replay_path = out / "replay.npz"
    if args.resume:
        if replay_path.is_file():
            saved_at = replay.load(replay_path)
            print(f"resumed at epoch {start} with {len(replay)} direction samples in the replay buffer")
            if saved_at != start:
                print(
                    f"warning: {replay_path} was saved at epoch {saved_at}, the checkpoint at {start}", file=sys.stderr
                )
        else:
            print(f"resumed at epoch {start}; the replay buffer starts empty (no {replay_path}: see --save-replay)")
    writer = SummaryWriter(str(out / "tb"))
    umpnet_bin = str(Path(__file__).resolve().parents[2] / "target" / "release" / "umpnet")
    command = "python -m umpnet_train.train " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
    stats = {
        "sim_s": 0.0, "probe_s": 0.0, "learn_s": 0.0, "collect_wall_s": 0.0, "positions": 0, "position_success": 0, "steps": 0,
        "dense_labels": 0, "aot_counts": [0, 0, 0],
    }  # fmt: skip
    t_start = time.perf_counter()
    commit = git_commit()  # now, not at each checkpoint: the code may be edited while a run goes on
    segments = [*segments, {"from_epoch": start, "git_commit": commit}]

    def provenance(epoch):
        wall = wall_before + time.perf_counter() - t_start
        return {
            "command": command,
            "seed": cfg.seed,
            "preset": args.preset,
            "git_commit": commit,
            "segments": segments,
            "epochs": epoch,
            "wall_seconds": wall,
            "simulation_share": stats["sim_s"] / max(stats["sim_s"] + stats["learn_s"], 1e-9),
            "trained_on": {"categories": categories, "split": "train instances", "physics": cfg.physics},
            "collection": f"ray, {args.ray} actors" if args.ray else "local",
            "torch": torch.__version__,
            **({"position_from": position_from} if position_from is not None else {}),
        }

    bar = tqdm(
        range(start, cfg.epochs), initial=start, total=cfg.epochs, desc="epochs", disable=not sys.stderr.isatty()
    )
    last = cfg.epochs  # the epoch the run ends at: cfg.epochs, or earlier under --time-limit
    for epoch in bar:
        t0 = time.perf_counter()
        if collection is not None:
            collection.collect(model, epoch, replay, dense, stats)
        else:
            collect(env, model, cfg, replay, dense, epoch, rng, stats)
        stats["collect_wall_s"] += time.perf_counter() - t0
        model.train()
        t0 = time.perf_counter()
        for _ in range(cfg.iterations_per_epoch):
            out_l = learner.update(
                replay, dense, rng,
                train_position=epoch >= cfg.position_start_epoch and not cfg.freeze_position,
                train_direction=epoch >= cfg.direction_start_epoch and not cfg.freeze_direction,
            )  # fmt: skip
        sched.step()
        stats["learn_s"] += time.perf_counter() - t0
        for k, v in out_l.items():
            writer.add_scalar(k, float(v.detach()), epoch)
        writer.add_scalar(
            "collect/position_success_rate", stats["position_success"] / max(stats["positions"], 1), epoch
        )
        writer.add_scalar("collect/sequence_length", sequence_length(cfg, epoch), epoch)
        share = stats["sim_s"] / max(stats["sim_s"] + stats["learn_s"], 1e-9)
        writer.add_scalar("time/simulation_share", share, epoch)
        if stats["probe_s"]:
            writer.add_scalar("time/dense_labels_per_s", stats["dense_labels"] / stats["probe_s"], epoch)
        bar.set_postfix(loss=f"{float(out_l['loss/total'].detach()):.3f}", sim=f"{share:.0%}")
        out_of_time = args.time_limit is not None and time.perf_counter() - t_start > args.time_limit
        if out_of_time:
            last = epoch + 1
        if (epoch + 1) % cfg.checkpoint_every == 0 or epoch + 1 == cfg.epochs or out_of_time:
            ck = {
                "config": dataclasses.asdict(cfg),
                "model": model.state_dict(),
                "optimizer": opt.state_dict(),
                "scheduler": sched.state_dict(),
                "numpy_rng": rng.bit_generator.state,
                "torch_rng": torch.get_rng_state(),
                "epoch": epoch + 1,
                "provenance": provenance(epoch + 1),
            }
            if cfg.save_replay:
                replay.save(replay_path, epoch + 1)
            torch.save(ck, out / "checkpoint.tmp")
            (out / "checkpoint.tmp").replace(ckpt_path)  # never leaves a half-written checkpoint
        if cfg.eval_every and (epoch + 1) % cfg.eval_every == 0:
            evaluate(model, cfg, out, umpnet_bin, writer, epoch + 1)
        if not sys.stderr.isatty() and (epoch + 1) % 10 == 0:
            print(
                f"epoch {epoch + 1}/{cfg.epochs} loss {float(out_l['loss/total'].detach()):.4f} sim share {share:.0%}",
                flush=True,
            )
        if out_of_time:
            print(f"--time-limit {args.time_limit:g} s: stopped after epoch {last} of {cfg.epochs}", flush=True)
            break
    writer.close()
    if collection is not None:
        collection.close()
    prov = provenance(last)
    print(
        f"trained {last} epochs in {prov['wall_seconds']:.0f} s; simulation {prov['simulation_share']:.0%} of the time"
    )
    print(f"AoT labels collected (-1, 0, +1): {stats['aot_counts']}")
    rate = stats["steps"] / max(stats["collect_wall_s"], 1e-9)
    where = f"{args.ray} Ray actors" if args.ray else "this process"
    print(f"collection ({where}): {stats['steps']} direction samples in {stats['collect_wall_s']:.1f} s ({rate:.1f}/s)")
    if stats["dense_labels"]:
        rate = stats["dense_labels"] / max(stats["probe_s"], 1e-9)
        print(f"dense labels: {stats['dense_labels']} in {stats['probe_s']:.0f} s ({rate:.0f} labels/s)")
    if args.export:
        worst = export_model(model.cpu(), cfg, args.export, prov)
        print(f"exported {args.export} (max |ONNX - PyTorch| = {worst:.2e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
