"""Candidate relabelling: the direction networks fine-tuned on the candidates
the runtime actually scores.

Training labels executed moves and a few probed directions per state, sampled
1:1:1 over the Arrow of Time's classes. The runtime asks something else: at
the states its own policy reaches, which of CEM's candidates moves the part,
and which way. There most candidates leave the part where it was (about two
thirds), and a head trained on balanced classes calls many of them forward or
back (diagnose: 95-97% of its AoT errors lie on the still class's border).

So this collects exactly that distribution, as DAgger does: the package's own
policy runs the training categories' training instances (on seeds neither
training nor diagnose uses), and at every state each CEM candidate is
simulated on a copy of the articulation (VecEnv.probe_directions). The
direction nets are then fine-tuned on those labels, the still class weighted
by --still-weight (1: the natural class frequencies), the position net
untouched. The labels are diagnose's: the
reference training code's "moved" threshold, signed against the reference
image's state (the start when exploring, the goal in the goal task).

    python -m umpnet_train.candidates collect ../models/umpnet-small ../runs/cands.npz --episodes 400
    python -m umpnet_train.candidates finetune CKPT ../runs/cands.npz ../runs/cand-ft --steps 2000 \
        --export ../runs/pkg --base ../models/umpnet-small

The test categories are never collected: they stay for diagnose and eval.
The natural frequencies have a cost: the paper's goal policy stops when no
candidate is called toward the goal, and on objects unlike the training
ones a head that calls more candidates still stops it sooner; a still
weight below 1 (the shipped package's 0.5) leans it back toward moving
(docs/relabelling.md). `--mirror P` shows that share of the training
states mirrored left-right (mirror.py; the shipped package's second round
used 0.25: docs/relabelling.md).
"""

from __future__ import annotations

import argparse
import copy
import json
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
import umpnet

from . import mirror
from .collect import TRAIN_CATEGORIES, device, to_long, to_torch
from .config import config_from_checkpoint
from .diagnose import episode_setup, true_aot
from .export import export_model
from .models import UMPNet

# Training environments take seeds seed*1000 + epoch + i and diagnose 7 000 000
# onwards; relabelling's scenes start here, so none of them is scored.
SEED_OFFSET = 9_000_000
TASKS = ("exploration", "goal")


@dataclass
class Settings:
    """Fine-tuning's defaults: a tenth of training's learning rate, since it
    starts from a trained model and must not forget the moves it learned."""

    steps: int = 2000
    batch_states: int = 16
    lr: float = 1e-4
    dist_loss_weight: float = 100.0  # as training's (config.dist_loss_weight)
    # The still class's weight in the cross-entropy: 1 keeps the natural
    # frequencies; below 1 leans the head toward calling a move, which the
    # paper's goal policy needs to keep going on unfamiliar objects.
    still_weight: float = 1.0
    # The share of training states shown mirrored left-right (beyond the
    # paper): the benchmark camera sits in the world's plane x = 0, so the
    # mirrored scene, with each candidate's x negated, is an equally valid
    # state with the same labels (a left-hinged door becomes a right-hinged one).
    mirror: float = 0.0
    seed: int = 0
    threads: int = 2


def collect(
    package: Path,
    episodes: int,
    seed: int = 0,
    epsilon: float = 0.2,
    n: int = 8,
    dataset_seed: int = 0,
    categories: list[str] | None = None,
    *,
    log=print,
) -> dict:
    """`episodes` per task on the training categories' training instances,
    the package's policy (the networks' own choice at each state, as the
    paper's) deciding; with probability `epsilon` a random one of its
    candidates is executed instead, so the states also cover the policy's
    near misses. `dataset_seed` picks the generated dataset the instances
    come from (0: the one training and eval use; others draw new instances
    of the same families). `categories` narrows the training categories
    (default: all twelve); a test category is refused, since its objects
    are what the fine-tuned model is scored on. Returns arrays, one row per state: image and reference
    (float16), pixel, mode (0 explore, 1 goal), candidates (K x 3, NaN
    padded), their AoT (-1, 0, +1; 2 where padded) and distance moved."""
    categories = training_categories(categories)
    policy = umpnet.Policy(str(package), seed=seed, threads=1)
    rng = np.random.default_rng(seed)
    rows: list[dict] = []  # one per state, each array with a leading axis of 1
    for t_i, task in enumerate(TASKS):
        env = umpnet.VecEnv(
            n, category=categories, split="train", seed=SEED_OFFSET + seed * 1000 + t_i,
            resolution=policy.resolution, task=task, physics="reference", dataset_seed=dataset_seed,
        )  # fmt: skip
        mode = "goal" if task == "goal" else "explore"
        done = 0
        while done < episodes:
            obs = env.reset()
            scenes = env.scenes
            pixels = [
                policy.position(obs["image"][i], obs["reference"][i] if task == "goal" else None) for i in range(n)
            ]
            obs, info = env.step_position(np.array(pixels, np.int64))
            start, goal, budget = episode_setup(scenes, np.array(info["joint"]), task)
            ref_value = goal if task == "goal" else start
            value = start.copy()
            # The last batch runs all n environments but records only the episodes asked for.
            counted = np.arange(n) < episodes - done
            live = np.array(info["valid"], bool)
            for t in range(int(budget.max())):
                live &= t < budget
                if not live.any():
                    break
                pix = np.maximum(obs["gripper_pixel"], 0)
                res = policy.direction_batch(obs["image"], obs["reference"], pix, mode)
                k = max(len(r["candidates"]) for r in res)
                cand = np.zeros((n, k, 3), np.float32)
                for i, r in enumerate(res):
                    c = np.asarray(r["candidates"], np.float32).reshape(-1, 3)
                    cand[i, : len(c)] = c
                    cand[i, len(c) :] = c[0] if len(c) else (0.0, 0.0, 1.0)
                probed = env.probe_directions(cand)
                for i in np.flatnonzero(live & counted & np.asarray(probed["active"])):
                    m = len(res[i]["candidates"])
                    after = probed["joint_after"][i, :m].astype(np.float64)
                    aot = true_aot(value[i], after, ref_value[i], probed["train_moved"][i, :m])
                    rows.append(
                        {
                            "image": obs["image"][i][None].astype(np.float16),
                            "reference": obs["reference"][i][None].astype(np.float16),
                            "pixel": pix[i][None].astype(np.int16),
                            "mode": np.array([task == "goal"], np.int8),
                            "candidates": cand[None, i, :m],
                            "aot": aot[None].astype(np.int8),
                            "dist": probed["r_dist"][None, i, :m].astype(np.float32),
                        }
                    )
                dirs = np.array([r["direction"] or [0.0, 0.0, 1.0] for r in res], np.float32)
                live &= np.array([r["direction"] is not None for r in res])
                explore = rng.random(n) < epsilon
                for i in np.flatnonzero(explore):
                    m = len(res[i]["candidates"])
                    if m:
                        dirs[i] = cand[i, rng.integers(m)]
                obs, _, sinfo = env.step_direction(dirs)
                value = np.where(live, np.asarray(sinfo["joint_after"], np.float64), value)
            done = min(done + n, episodes)
            log(f"{task}: {done}/{episodes} episodes, {len(rows)} states")
    if not rows:
        raise ValueError(f"{package}: no grasp held in {episodes} episodes per task, so no candidate to label")
    return merge(rows)


def training_categories(categories: list[str] | None) -> list[str]:
    """`categories`, checked to be training categories (all twelve for None)."""
    if categories is None:
        return list(TRAIN_CATEGORIES)
    unknown = [c for c in categories if c not in TRAIN_CATEGORIES]
    if unknown or not categories:
        raise ValueError(
            f"--categories {','.join(unknown) or '(empty)'}: expected training categories "
            f"({', '.join(TRAIN_CATEGORIES)}); the test categories are never collected"
        )
    return categories


def candidate_losses(model: UMPNet, batch: dict, dist_loss_weight: float, still_weight: float = 1.0) -> dict:
    """Cross-entropy of the AoT head over every real candidate, the still
    class weighted by `still_weight` (1: the natural frequencies), plus
    training's distance regression."""
    k = batch["candidates"].shape[1]
    de, ae = model.encoder(to_torch(batch["image"]), to_torch(batch["reference"]), to_long(batch["pixel"]))
    dirs = np.nan_to_num(batch["candidates"].reshape(-1, 3), nan=0.0)
    pred_dist, logits = model.decoder(de.repeat_interleave(k, 0), ae.repeat_interleave(k, 0), to_torch(dirs))
    real = torch.from_numpy(batch["aot"].reshape(-1) != 2).to(device())
    target = to_long(np.where(batch["aot"].reshape(-1) == 2, 1, batch["aot"].reshape(-1) + 1))
    weight = torch.tensor([1.0, still_weight, 1.0], device=logits.device)
    aot = F.cross_entropy(logits[real], target[real], weight=weight)
    dist = F.mse_loss(pred_dist[real], to_torch(batch["dist"].reshape(-1))[real])
    return {
        "loss/aot": aot,
        "loss/dist": dist,
        "loss/total": aot + dist_loss_weight * dist,
        "metric/aot_accuracy": (logits[real].argmax(1) == target[real]).float().mean(),
    }


def mirrored(batch: dict, which: np.ndarray) -> dict:
    """`batch` with the states at indices `which` mirrored left-right
    (umpnet_train.mirror: images by the runtime's own mirror, the grasp
    pixel's column reflected, each candidate direction's x negated). Labels
    are unchanged, since physics is symmetric under the mirror."""
    out = dict(batch)
    (out["image"], out["reference"]), (out["pixel"],), (out["candidates"],), _ = mirror.states(
        which, [batch["image"], batch["reference"]], [batch["pixel"]], [batch["candidates"]], []
    )
    return out


def finetune(checkpoint: Path, data: dict, out: Path, s: Settings, log=print) -> Path:
    """Fine-tunes the direction nets of `checkpoint` on `data` (from
    `collect`); writes `out/checkpoint.pt` with a provenance segment and
    returns its path. A tenth of the states are held out to report accuracy."""
    torch.manual_seed(s.seed)
    torch.set_num_threads(s.threads)
    ck = torch.load(checkpoint, map_location="cpu", weights_only=False)
    cfg = config_from_checkpoint(ck["config"])
    model = UMPNet(cfg).to(device())
    model.load_state_dict(ck["model"])
    for p in model.position.parameters():
        p.requires_grad_(False)
    params = [p for p in model.parameters() if p.requires_grad]
    opt = torch.optim.Adam(params, lr=s.lr, betas=tuple(cfg.adam_betas))
    rng = np.random.default_rng(s.seed)
    order = rng.permutation(len(data["mode"]))
    held = order[: max(len(order) // 10, 1)]
    train = order[len(held) :]

    def batch(idx):
        return {k: v[idx] for k, v in data.items()}

    def held_accuracy():
        model.eval()
        hits = total = 0
        with torch.no_grad():
            for i in range(0, len(held), 64):
                b = batch(held[i : i + 64])
                scored = candidate_losses(model, b, s.dist_loss_weight, s.still_weight)
                n = int((b["aot"] != 2).sum())
                hits, total = hits + float(scored["metric/aot_accuracy"]) * n, total + n
        model.train()
        return hits / max(total, 1)

    before = held_accuracy()
    log(f"held-out states' AoT accuracy before: {before:.3f}")
    t0 = time.perf_counter()
    model.train()
    for step in range(1, s.steps + 1):
        b = batch(rng.choice(train, s.batch_states))
        b = mirrored(b, mirror.chosen(rng, s.batch_states, s.mirror))
        losses = candidate_losses(model, b, s.dist_loss_weight, s.still_weight)
        opt.zero_grad()
        losses["loss/total"].backward()
        opt.step()
        if step % 100 == 0 or step == s.steps:
            v = {k: float(x.detach()) for k, x in losses.items()}
            log(
                f"step {step}/{s.steps}: aot {v['loss/aot']:.3f} dist {v['loss/dist']:.4f} "
                f"accuracy {v['metric/aot_accuracy']:.3f} ({time.perf_counter() - t0:.0f} s)"
            )
    accuracy = held_accuracy()
    log(f"held-out states' AoT accuracy after: {accuracy:.3f}")
    out.mkdir(parents=True, exist_ok=True)
    provenance = copy.deepcopy(ck.get("provenance", {}))
    provenance.setdefault("segments", []).append(
        {
            "from_epoch": ck.get("epoch"),
            "what": "candidate relabelling (umpnet_train.candidates): the direction nets fine-tuned on the CEM "
            "candidates of the package's own policy, labelled by simulation, the still class weighted by "
            "settings.still_weight (1: natural class frequencies), a share settings.mirror of the "
            "sampled states shown mirrored left-right (0: none)",
            "states": len(data["mode"]),
            "labels": int((data["aot"] != 2).sum()),
            "settings": s.__dict__,
            "held_out_aot_accuracy": {"before": before, "after": accuracy},
            "wall_seconds": time.perf_counter() - t0,
        }
    )
    ck = {**ck, "model": model.state_dict(), "provenance": provenance}
    ck.pop("optimizer", None)  # training's Adam state no longer matches these weights
    ck.pop("scheduler", None)
    path = out / "checkpoint.pt"
    torch.save(ck, path)
    return path


def export_package(checkpoint: Path, base: Path, out: Path) -> None:
    """The fine-tuned checkpoint as a package: its ONNX networks, with the
    joint network and grasp rule of the `base` package it was collected with."""
    ck = torch.load(checkpoint, map_location="cpu", weights_only=False)
    cfg = config_from_checkpoint(ck["config"])
    model = UMPNet(cfg)
    model.load_state_dict(ck["model"])
    export_model(model, cfg, out, ck.get("provenance", {}))
    base_meta = json.loads((base / "model.json").read_text())
    meta = json.loads((out / "model.json").read_text())
    for key in ("joint", "grasp"):
        if key in base_meta:
            meta[key] = base_meta[key]
    files = base_meta.get("files", {})
    if "joint" in files:
        shutil.copyfile(base / files["joint"], out / files["joint"])
        meta["files"]["joint"] = files["joint"]
    (out / "model.json").write_text(json.dumps(meta, indent=2))


def save(data: dict, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **data)
    tmp.replace(path)


def load(path: Path) -> dict:
    with np.load(path) as f:
        return {k: f[k] for k in f.files}


def merge(parts: list[dict]) -> dict:
    """Several `collect` outputs as one; files whose states had different
    numbers of candidates are padded to the widest."""
    k = max(d["candidates"].shape[1] for d in parts)
    pad = {"candidates": np.nan, "aot": 2, "dist": 0.0}
    out = {}
    for key in parts[0]:
        if key not in pad:
            out[key] = np.concatenate([d[key] for d in parts])
            continue
        padded = []
        for d in parts:
            widths = [(0, 0), (0, k - d[key].shape[1])] + [(0, 0)] * (d[key].ndim - 2)
            padded.append(np.pad(d[key], widths, constant_values=pad[key]))
        out[key] = np.concatenate(padded)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    c = sub.add_parser("collect", help="label the package's own candidates on the training categories")
    c.add_argument("package", type=Path)
    c.add_argument("out", type=Path, help="the .npz to write")
    c.add_argument("--episodes", type=int, default=400, help="per task")
    c.add_argument("--epsilon", type=float, default=0.2)
    c.add_argument("--seed", type=int, default=0)
    c.add_argument(
        "--dataset-seed", type=int, default=0,
        help="the generated dataset the training instances come from (0: training's; others: new instances)",
    )  # fmt: skip
    c.add_argument(
        "--categories", type=lambda s: [c.strip() for c in s.split(",") if c.strip()],
        help="comma-separated training categories to collect on (default: all twelve)",
    )  # fmt: skip
    f = sub.add_parser("finetune", help="fine-tune a checkpoint's direction nets on collected candidates")
    f.add_argument("checkpoint", type=Path)
    f.add_argument("data", type=Path, nargs="+", help=".npz files from collect")
    f.add_argument("out", type=Path, help="run directory for checkpoint.pt")
    for name, default in Settings().__dict__.items():
        f.add_argument(f"--{name.replace('_', '-')}", type=type(default), default=default)
    f.add_argument("--export", type=Path, help="also write a package here")
    f.add_argument("--base", type=Path, help="the package whose joint net and grasp the export keeps")
    a = p.parse_args(argv)
    if a.command == "collect":
        if not (a.package / "model.json").is_file():
            p.error(f"{a.package}: not a model package (no model.json)")
        if a.episodes < 1 or not 0.0 <= a.epsilon <= 1.0 or a.dataset_seed < 0:
            p.error("--episodes must be at least 1, --epsilon within [0, 1] and --dataset-seed not negative")
        try:
            training_categories(a.categories)
        except ValueError as e:
            p.error(str(e))
        save(
            collect(a.package, a.episodes, a.seed, a.epsilon, dataset_seed=a.dataset_seed, categories=a.categories),
            a.out,
        )
        print(f"wrote {a.out}")
        return 0
    if not a.still_weight > 0 or a.steps < 1 or a.batch_states < 1 or not a.lr > 0 or not 0 <= a.mirror <= 1:
        p.error(
            "--still-weight and --lr must be positive, --steps and --batch-states at least 1, --mirror within [0, 1]"
        )
    for path in [a.checkpoint, *a.data]:
        if not path.is_file():
            p.error(f"{path}: no such file")
    if a.export is not None and a.base is None:
        p.error("--export needs --base (the package whose joint net and grasp rule to keep)")
    data = merge([load(path) for path in a.data])
    settings = Settings(**{name: getattr(a, name) for name in Settings().__dict__})
    path = finetune(a.checkpoint, data, a.out, settings)
    print(f"wrote {path}")
    if a.export is not None:
        export_package(path, a.base, a.export)
        print(f"wrote {a.export}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
