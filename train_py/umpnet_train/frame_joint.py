"""Single-frame joint inference (beyond the paper): a joint's type, axis and
origin from the articulation flow a position net predicts on one RGB-D frame,
measured against the simulator's truth.

    python -m umpnet_train.frame_joint CHECKPOINT [--split test] [--episodes 20]

The checkpoint must have the auxiliary fields head (`train --aux-fields`);
with `--aux-flow scaled` its flow carries each point's relative speed, which
a hinge needs (unit flow on a flat door is the same vector everywhere).

For each scene the grasp is the oracle's, on the part that moves, so the
measure is of the joint inference alone. The part is the predicted movable
pixels connected to the grasp over the depth surface. Each point's predicted
flow v is fitted to a rigid motion, v = w x (p - centroid) + c: a hinge when
the rotation explains the flow much better than a constant does (axis w, the
origin where w x c puts it), else a slide along c. The truth is the same fit
on the simulator's scaled flow of the grasped part, which is exact.
"""

from __future__ import annotations

import argparse
import json
from collections import deque
from pathlib import Path

import numpy as np
import torch
import umpnet

from .config import config_from_checkpoint
from .models import UMPNet

# The rotation must explain this much more of the flow than a constant does.
HINGE_GAIN = 2.0
# Neighbouring pixels farther apart than this (m) are on different surfaces.
SURFACE_STEP = 0.03
# The movable head is trained with a plain BCE on images where most pixels are
# static, so it is shy: measured means of 0.2-0.4 on parts, 0.02-0.03 off them.
MOVABLE_PROB = 0.1
# Or a predicted flow this long: scaled flow is zero off the moving parts.
MOVING_FLOW = 0.1


def skew(x: np.ndarray) -> np.ndarray:
    return np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])


def fit_joint(points: np.ndarray, flow: np.ndarray) -> dict | None:
    """The rigid motion that best explains per-point flow (n x 3 each):
    {"type", "axis", "origin" (revolute)}, or None without enough points."""
    if len(points) < 3 or not np.isfinite(flow).all():
        return None
    centroid = points.mean(0)
    a = np.zeros((3 * len(points), 6))
    for i, x in enumerate(points - centroid):
        a[3 * i : 3 * i + 3, 0:3] = -skew(x)
        a[3 * i : 3 * i + 3, 3:6] = np.eye(3)
    b = flow.reshape(-1)
    solution, *_ = np.linalg.lstsq(a, b, rcond=None)
    w, c = solution[:3], solution[3:]
    rotating = np.sum((a @ solution - b) ** 2)
    sliding = np.sum((flow - flow.mean(0)) ** 2)
    if np.linalg.norm(w) > 1e-9 and rotating * HINGE_GAIN < sliding:
        origin = centroid + np.cross(w, c) / np.dot(w, w)
        return {"type": "revolute", "axis": w / np.linalg.norm(w), "origin": origin}
    mean = flow.mean(0)
    if np.linalg.norm(mean) < 1e-9:
        return None
    return {"type": "prismatic", "axis": mean / np.linalg.norm(mean), "origin": None}


def part_pixels(image: np.ndarray, movable: np.ndarray, seed: tuple[int, int]) -> list[tuple[int, int]]:
    """Pixels connected to `seed` through movable pixels on one surface."""
    h, w = movable.shape
    points, valid = image[..., 0:3], image[..., 9] > 0
    seen, queue, out = {seed}, deque([seed]), []
    while queue:
        r, c = queue.popleft()
        out.append((r, c))
        for n in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
            if (
                0 <= n[0] < h
                and 0 <= n[1] < w
                and n not in seen
                and valid[n]
                and movable[n]
                and np.linalg.norm(points[n] - points[r, c]) < SURFACE_STEP
            ):
                seen.add(n)
                queue.append(n)
    return out


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(min(1.0, abs(float(np.dot(a, b)))))))


def load_source(source: Path):
    """What predicts the joint: a model package with a JointNet (`joint.onnx`,
    voted by the Rust runtime, as `umpnet infer` does), a JointNet checkpoint
    (`joint_net`'s joint.pt, the same vote), or a policy checkpoint trained
    with `--aux-fields` (the rigid-motion fit of its flow head). Returns the
    image size and a function (image, grasp, true part or None) -> (estimate,
    predicted flow or None)."""
    if (source / "model.json").is_file():
        policy = umpnet.Policy(str(source))
        if not json.loads((source / "model.json").read_text())["files"].get("joint"):
            raise ValueError(f"{source}: the package has no JointNet (files.joint)")

        def from_package(image, grasp, _part):
            return rust_estimate(policy.frame_joint(image, grasp)), None

        return policy.resolution, from_package
    ck = torch.load(source, map_location="cpu", weights_only=False)
    if "step" in ck and "widths" in ck["config"]:
        from .joint_net import load

        model, cfg = load(source)

        def from_joint_net(image, grasp, _part):
            with torch.no_grad():
                fields = model(torch.from_numpy(image[None]))[0].numpy()
            estimate = umpnet._umpnet.joint_from_fields(image, np.ascontiguousarray(fields), grasp)
            return rust_estimate(estimate), fields[2:5].transpose(1, 2, 0)

        return (cfg.height, cfg.width), from_joint_net
    cfg = config_from_checkpoint(ck["config"])
    if cfg.aux_fields <= 0:
        raise ValueError(f"{source}: trained without --aux-fields, so it predicts no flow")
    model = UMPNet(cfg)
    model.load_state_dict(ck["model"])
    model.eval()

    def from_flow_head(image, grasp, true_part):
        with torch.no_grad():
            _, fields = model.position.forward_fields(torch.from_numpy(image[None]))
        flow = fields[0, :3].permute(1, 2, 0).numpy()
        if true_part is not None:
            movable = true_part.copy()
        else:
            movable = (torch.sigmoid(fields[0, 3]).numpy() > MOVABLE_PROB) | (
                np.linalg.norm(flow, axis=-1) > MOVING_FLOW
            )
        movable[grasp] = True
        rows_, cols_ = np.array(part_pixels(image, movable, grasp)).T
        return fit_joint(image[rows_, cols_, 0:3], flow[rows_, cols_]), flow

    return (cfg.height, cfg.width), from_flow_head


def rust_estimate(estimate: dict | None) -> dict | None:
    if estimate is None:
        return None
    point = estimate["point"]
    return {"type": estimate["type"], "axis": np.array(estimate["axis"]),
            "origin": None if point is None else np.array(point)}  # fmt: skip


def measure(
    source: Path, split: str, episodes: int, seed: int = 0, part: str = "predicted", objects: Path | None = None
) -> dict:
    """`part`: predicted (the part the network sees, connected to the grasp)
    or truth (the simulator's pixels of the grasped part, so the flow alone is
    measured; a policy checkpoint's flow head only). With `objects`, the rows
    are its object folders (each with a mobility.urdf, as `umpnet eval
    --objects` reads them) instead of the split's categories."""
    (height, width), predict = load_source(source)
    if part == "truth" and predict.__name__ != "from_flow_head":
        raise ValueError("--part truth measures a policy checkpoint's flow head; a JointNet finds its own part")
    rows = []
    if objects is None:
        # As the benchmark: the test categories' instances, or the training
        # categories' held-out ones (never those a model was trained on).
        scenes = {name: {"category": name, "split": "test"} for name, s, _ in umpnet.categories() if s == split}
    else:
        folders = sorted(d for d in objects.iterdir() if (d / "mobility.urdf").is_file())
        if not folders:
            raise ValueError(f"{objects}: no object folder (with a mobility.urdf) in it")
        scenes = {d.name: {"object_dir": str(d)} for d in folders}
    for category, where in scenes.items():
        for k in range(episodes):
            env = umpnet.Env(seed=seed + k, task="exploration", copy=True, resolution=(height, width), **where)
            image = env.reset()["image"]
            grasp = tuple(int(v) for v in env.scripted_action("oracle"))
            truth_fields = env.articulation_fields()
            joint = truth_fields["joint"].reshape(height, width)
            j = joint[grasp]
            if j < 0:
                continue
            on_part = joint == j
            true_flow = truth_fields["flow"].reshape(height, width, 3) * truth_fields["speed"].reshape(height, width, 1)
            truth = fit_joint(image[..., 0:3][on_part], true_flow[on_part])
            if truth is None:
                continue
            estimate, flow = predict(image, grasp, on_part if part == "truth" else None)
            row = {"category": category, "index": k, "true_type": truth["type"]}
            if flow is not None:
                # How the predicted flow errs on the true part: its directions, and its speeds.
                pred, true = flow[on_part], true_flow[on_part]
                norms = np.linalg.norm(pred, axis=1) * np.linalg.norm(true, axis=1)
                row["flow_cosine"] = float(np.median(np.sum(pred * true, axis=1) / np.maximum(norms, 1e-9)))
                speeds = np.linalg.norm(pred, axis=1), np.linalg.norm(true, axis=1)
                if min(np.std(speeds[0]), np.std(speeds[1])) > 1e-6:
                    row["speed_correlation"] = float(np.corrcoef(*speeds)[0, 1])
            if estimate is None:
                row.update(type=None, axis_error_deg=None)
            else:
                row.update(type=estimate["type"], axis_error_deg=angle_deg(estimate["axis"], truth["axis"]))
                if estimate["type"] == "revolute" and truth["type"] == "revolute":
                    offset = estimate["origin"] - truth["origin"]
                    along = truth["axis"] * np.dot(offset, truth["axis"])
                    row["origin_error_m"] = float(np.linalg.norm(offset - along))
            rows.append(row)
    return {"part": part, **summarize(rows, split, episodes, str(source))}


def median(values) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.median(kept)) if kept else None


def summarize(rows: list[dict], split: str, episodes: int, source: str) -> dict:
    def stats(sel):
        # A scene the fit gave no joint for counts as the worst error, 90 degrees.
        errors = [r["axis_error_deg"] if r["axis_error_deg"] is not None else 90.0 for r in sel]
        return {
            "n": len(sel),
            "median_axis_error_deg": median(errors),
            "within_10_deg": float(np.mean([e <= 10 for e in errors])) if errors else None,
            "type_accuracy": float(np.mean([r["type"] == r["true_type"] for r in sel])) if sel else None,
            "median_origin_error_m": median([r.get("origin_error_m") for r in sel]),
            "median_flow_cosine": median([r.get("flow_cosine") for r in sel]),
            "median_speed_correlation": median([r.get("speed_correlation") for r in sel]),
        }

    categories = sorted({r["category"] for r in rows})
    return {
        "checkpoint": source,
        "split": split,
        "episodes_per_category": episodes,
        "all": stats(rows),
        "by_true_type": {t: stats([r for r in rows if r["true_type"] == t]) for t in ("revolute", "prismatic")},
        "by_category": {c: stats([r for r in rows if r["category"] == c]) for c in categories},
        "episodes": rows,
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source", type=Path, help="a package with a JointNet, a JointNet checkpoint, or a policy checkpoint")
    p.add_argument(
        "--split",
        default="test",
        choices=("train", "test"),
        help="the test categories, or the training categories' held-out instances",
    )
    p.add_argument("--episodes", type=int, default=20, help="scenes per category")
    p.add_argument(
        "--part",
        default="predicted",
        choices=("predicted", "truth"),
        help="the grasped part's pixels: what the network predicts as moving, or the simulator's (flow alone)",
    )
    p.add_argument("--objects", type=Path, help="score these object folders (e.g. data/external) instead of the split")
    p.add_argument("--json", type=Path, help="write the whole report here")
    a = p.parse_args(argv)
    try:
        report = measure(a.source, a.split, a.episodes, part=a.part, objects=a.objects)
    except (OSError, ValueError, KeyError) as e:
        p.error(str(e))
    if a.json:
        a.json.write_text(json.dumps(report, indent=2) + "\n")

    def cell(v, spec):
        return "-" if v is None else format(v, spec)

    print(
        f"{'':18s} {'n':>4s} {'median axis error':>18s} {'<= 10 deg':>10s} {'type right':>11s} "
        f"{'origin error':>13s} {'flow cosine':>12s} {'speed corr.':>12s}"
    )
    for name, s in [("all", report["all"]), *report["by_true_type"].items(), *report["by_category"].items()]:
        if s["n"]:
            print(
                f"{name:18s} {s['n']:4d} {s['median_axis_error_deg']:17.1f}° {s['within_10_deg']:10.2f} "
                f"{s['type_accuracy']:11.2f} {cell(s['median_origin_error_m'], '.3f'):>11s} m "
                f"{cell(s['median_flow_cosine'], '.2f'):>12s} {cell(s['median_speed_correlation'], '.2f'):>12s}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
