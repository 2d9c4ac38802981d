"""JointNet (beyond the paper): a joint's type, axis and origin from one RGB-D
frame, trained on the simulator's dense articulation labels alone.

    python -m umpnet_train.joint_net --out ../runs/joint [--steps 3000] [--mirror 0.5] [--resume]
    python -m umpnet_train.joint_net --out ../runs/joint --export ../models/umpnet-small

A U-Net reads the observation (N x H x W x 10, as the position network does)
and predicts, at every pixel (FlowBot++'s dense articulation parameters):

- whether the pixel is on a part a joint moves (1 logit);
- whether that joint is a hinge rather than a slide (1 logit);
- the scaled articulation flow: the opening direction times the point's speed
  relative to its part's fastest point (3);
- the joint's axis, up to sign (3);
- for a hinge, the vector from the point to the nearest point on its axis (3, m).

A unit flow or a speed is a poor cue for where a hinge is (on a flat door every
point moves the same way, and the speed must be read across the whole part);
the projection to the axis is learnt per pixel and voted over the part.
`umpnet_policy::joint` does the vote in the runtime, from the exported
`joint.onnx`; `frame_joint` measures it against the simulator.

The frames are the training categories' training instances at random joint
states, some with the gripper holding the part after a few oracle moves; the
test categories and the training categories' held-out instances are never
seen.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch.nn import functional as F

from .models import CHANNELS, Normalize, UNet

if TYPE_CHECKING:
    import umpnet

# Output channels of the exported network, in this order.
OUTPUTS = (
    "movable",
    "revolute",
    "flow_x",
    "flow_y",
    "flow_z",
    "axis_x",
    "axis_y",
    "axis_z",
    "to_axis_x",
    "to_axis_y",
    "to_axis_z",
)


@dataclass
class JointConfig:
    height: int = 96
    width: int = 128
    widths: tuple[int, ...] = (16, 32, 64, 128)
    frames: int = 6000  # the dataset: frames generated once from `seed`
    steps: int = 6000
    batch: int = 16
    lr: float = 2e-3
    max_oracle_moves: int = 3  # frames after 0..N oracle moves (the gripper visible after a grasp)
    # Each image's colours under a random gain and offset per channel (a grey
    # image one time in four), so that parts are told by their shape, not
    # their paint. Off by default: with it (and 8000 frames) the test
    # categories' median axis error was 14.9 degrees against 12.3 without.
    color_jitter: bool = False
    # The share of each batch's frames shown mirrored left-right (the
    # policy's `train --mirror`, umpnet_train.mirror): a hinge on the left
    # becomes one on the right, a sash sliding right one sliding left.
    mirror: float = 0.0
    seed: int = 0


class JointNet(torch.nn.Module):
    def __init__(self, cfg: JointConfig):
        super().__init__()
        self.norm = Normalize()
        self.unet = UNet(CHANNELS, tuple(cfg.widths), len(OUTPUTS), global_context=True)

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        """observation N x H x W x 10 -> N x 11 x H x W (OUTPUTS)."""
        return self.unet(self.norm(observation.permute(0, 3, 1, 2)))


def joint_labels(image: np.ndarray, fields: dict) -> dict:
    """Per-pixel labels of one frame from the simulator's fields: each joint's
    exact axis and origin are the rigid motion its exact scaled flow fits."""
    from .frame_joint import fit_joint

    h, w = fields["joint"].shape
    joint = fields["joint"]
    scaled = fields["flow"] * fields["speed"][..., None]
    kind = np.full((h, w), -1, np.int8)  # -1 off parts or unknown, 0 slide, 1 hinge
    axis = np.zeros((h, w, 3), np.float32)
    to_axis = np.zeros((h, w, 3), np.float32)
    points = image[..., 0:3]
    for j in np.unique(joint[joint >= 0]):
        on = joint == j
        fit = fit_joint(points[on], scaled[on])
        if fit is None:
            continue
        axis[on] = fit["axis"]
        if fit["type"] == "revolute":
            kind[on] = 1
            p = points[on] - fit["origin"]
            to_axis[on] = np.outer(p @ fit["axis"], fit["axis"]) - p
        else:
            kind[on] = 0
    return {"movable": joint >= 0, "kind": kind, "flow": scaled, "axis": axis, "to_axis": to_axis}


def frame(env: umpnet.Env, rng: np.random.Generator, max_moves: int) -> tuple[np.ndarray, dict]:
    """One frame at a random state: a new scene, then 0..max_moves oracle moves."""
    obs = env.reset()
    moves = int(rng.integers(0, max_moves + 1))
    if moves:
        pixel = env.scripted_action("oracle")
        obs, info = env.step_position(int(pixel[0]), int(pixel[1]))
        for _ in range(moves - 1):
            if not info.get("valid", True):
                break
            d = env.scripted_action("oracle")
            if d is None:
                break
            obs, _, info = env.step_direction([float(v) for v in d])
    image = obs["image"].copy()
    return image, joint_labels(image, env.articulation_fields())


# Frames are made in chunks of this many, each from its own seeds, so that
# the dataset is the same whatever the number of worker processes.
CHUNK = 500


def _empty(frames: int, h: int, w: int) -> dict[str, np.ndarray]:
    return {
        "image": np.zeros((frames, h, w, CHANNELS), np.float16),
        "movable": np.zeros((frames, h, w), bool),
        "kind": np.zeros((frames, h, w), np.int8),
        "flow": np.zeros((frames, h, w, 3), np.float16),
        "axis": np.zeros((frames, h, w, 3), np.float16),
        "to_axis": np.zeros((frames, h, w, 3), np.float16),
    }


def make_chunk(cfg: JointConfig, chunk: int, size: int = CHUNK) -> dict[str, np.ndarray]:
    """Frames [chunk * size, ...) of the dataset, from seeds of their own."""
    # Here, not at the top: the fixture exports a JointNet before the
    # bindings are built (make fixture), and that needs no frames.
    import umpnet

    first = chunk * size
    count = min(size, cfg.frames - first)
    rng = np.random.default_rng([cfg.seed, chunk])
    names = [n for n, split, _ in umpnet.categories() if split == "train"]
    envs = {
        n: umpnet.Env(
            n,
            seed=cfg.seed + 1000 * chunk + i,
            task="exploration",
            split="train",
            copy=True,
            resolution=(cfg.height, cfg.width),
        )
        for i, n in enumerate(names)
    }
    data = _empty(count, cfg.height, cfg.width)
    for i in range(count):
        image, labels = frame(envs[names[(first + i) % len(names)]], rng, cfg.max_oracle_moves)
        data["image"][i] = image
        for k, v in labels.items():
            data[k][i] = v
    return data


def make_dataset(cfg: JointConfig, workers: int = 1, size: int = CHUNK) -> dict[str, np.ndarray]:
    """`cfg.frames` frames, spread evenly over the training categories, made
    by `workers` processes (the same frames for any number) in chunks of
    `size`."""
    import contextlib
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    chunks = range((cfg.frames + size - 1) // size)
    data = _empty(cfg.frames, cfg.height, cfg.width)
    with contextlib.ExitStack() as stack:
        run = map
        if workers > 1:
            # spawn, not fork: the parent may already hold threads (PyTorch's, CUDA's).
            spawn = multiprocessing.get_context("spawn")
            run = stack.enter_context(ProcessPoolExecutor(min(workers, len(chunks)), mp_context=spawn)).map
        parts = run(make_chunk, [cfg] * len(chunks), chunks, [size] * len(chunks))
        for chunk, part in zip(chunks, parts, strict=True):
            for k, v in part.items():
                data[k][chunk * size : chunk * size + len(v)] = v
    return data


def joint_losses(out: torch.Tensor, batch: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    movable = batch["movable"]
    valid = batch["image"][..., 9] > 0
    kind = batch["kind"]
    known, hinge = kind >= 0, kind == 1
    o = out.permute(0, 2, 3, 1)  # N x H x W x 11
    # Parts are a small share of an image: weigh them as much as the rest.
    share = movable[valid].float().mean().clamp(1e-3, 0.5)
    weight = torch.where(movable, 0.5 / share, 0.5 / (1 - share))[valid]
    losses = {
        "movable": F.binary_cross_entropy_with_logits(o[..., 0][valid], movable[valid].float(), weight=weight),
    }
    if known.any():
        # Hinges cover more pixels than slides: weigh the two kinds alike.
        h_share = hinge[known].float().mean().clamp(0.05, 0.95)
        kind_weight = torch.where(hinge[known], 0.5 / h_share, 0.5 / (1 - h_share))
        losses["revolute"] = F.binary_cross_entropy_with_logits(
            o[..., 1][known], hinge[known].float(), weight=kind_weight
        )
        losses["flow"] = (o[..., 2:5][known] - batch["flow"][known]).pow(2).sum(-1).mean()
        cos = F.cosine_similarity(o[..., 5:8][known], batch["axis"][known], dim=-1, eps=1e-6)
        losses["axis"] = (1 - cos.abs()).mean()
    if hinge.any():
        losses["to_axis"] = F.smooth_l1_loss(o[..., 8:11][hinge], batch["to_axis"][hinge], beta=0.05) * 10
    return losses


def mirror_frames(batch: dict[str, torch.Tensor], which: np.ndarray) -> None:
    """In place: the frames at `which` of a training batch mirrored
    left-right by `umpnet_train.mirror`'s rules, the ones `train --mirror`
    uses: the observation by the runtime's mirror, the part labels with
    their columns reversed, and the flow and axis fields with x negated too.
    The chosen frames make one round trip to the CPU."""
    from . import mirror

    if not len(which):
        return
    idx = torch.from_numpy(which).to(batch["image"].device)
    for keys, rule in (
        (("image",), mirror.images),
        (("movable", "kind"), mirror.columns),
        (("flow", "axis", "to_axis"), mirror.fields),
    ):
        for k in keys:
            part = batch[k][idx]
            batch[k][idx] = torch.from_numpy(rule(part.cpu().numpy())).to(part.device)


def jitter_colors(image: torch.Tensor, rng: np.random.Generator) -> None:
    """In place on N x H x W x 10 observations: rgb' = rgb x gain + offset,
    clipped to [0, 1], per image and channel; one image in four made grey
    (and kept so)."""
    n = image.shape[0]
    rgb = image[..., 3:6]
    grey = torch.from_numpy(rng.random(n) < 0.25).to(image.device)
    rgb[grey] = rgb[grey].mean(-1, keepdim=True).expand(-1, -1, -1, 3).clone()
    gain = torch.from_numpy(rng.uniform(0.6, 1.4, (n, 1, 1, 3)).astype(np.float32)).to(image.device)
    offset = torch.from_numpy(rng.uniform(-0.2, 0.2, (n, 1, 1, 3)).astype(np.float32)).to(image.device)
    # A grey image stays grey: one gain and offset for its three channels.
    gain[grey] = gain[grey][..., :1].expand(-1, -1, -1, 3).clone()
    offset[grey] = offset[grey][..., :1].expand(-1, -1, -1, 3).clone()
    image[..., 3:6] = (rgb * gain + offset).clamp(0, 1)


def train(
    cfg: JointConfig,
    out: Path,
    resume: bool,
    device: str = "cpu",
    workers: int = 1,
    time_limit: float | None = None,
) -> JointNet:
    """Trains to `cfg.steps` (or until `time_limit` seconds have passed, with
    a checkpoint that `resume` continues) on `device`; the frames come from
    `workers` processes. Returns the model, on the CPU."""
    t_start = time.perf_counter()
    torch.manual_seed(cfg.seed)
    # On `device` before the optimiser: a resumed Adam state follows its parameters there.
    model = JointNet(cfg).to(device)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    step = 0
    out.mkdir(parents=True, exist_ok=True)
    checkpoint = out / "joint.pt"
    if resume and checkpoint.exists():
        ck = torch.load(checkpoint, map_location="cpu", weights_only=False)
        model.load_state_dict(ck["model"])
        if "optimizer" in ck:
            opt.load_state_dict(ck["optimizer"])
        else:
            # A shipped checkpoint keeps its weights alone (a finished run, kept small).
            print(f"{checkpoint}: no optimiser state; Adam starts afresh from the weights", flush=True)
            for group in opt.param_groups:
                group["initial_lr"] = cfg.lr  # the cosine schedule resumes at `step` from it
        step = ck["step"]
    from .train import git_commit

    commit = git_commit()  # at the start: the code may be edited while the run goes on
    t0 = time.perf_counter()
    # The frames stay half precision where they are kept (on the GPU when
    # training there); a batch is made full precision as it is drawn.
    data = {k: torch.from_numpy(v).to(device) for k, v in make_dataset(cfg, workers).items()}
    print(f"{cfg.frames} frames in {time.perf_counter() - t0:.0f} s", flush=True)
    where = torch.cuda.get_device_name() if str(device).startswith("cuda") else "cpu"
    rng = np.random.default_rng(cfg.seed + step)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, cfg.steps, last_epoch=step - 1 if step else -1)
    model.train()
    t0 = time.perf_counter()
    while step < cfg.steps:
        idx = torch.from_numpy(np.sort(rng.choice(cfg.frames, cfg.batch, replace=False))).to(device)
        batch = {k: v[idx].float() if v.dtype == torch.float16 else v[idx] for k, v in data.items()}
        batch["kind"] = batch["kind"].long()
        if cfg.color_jitter:
            jitter_colors(batch["image"], rng)
        if cfg.mirror > 0:
            from .mirror import chosen

            mirror_frames(batch, chosen(rng, cfg.batch, cfg.mirror))
        losses = joint_losses(model(batch["image"]), batch)
        total = sum(losses.values())
        opt.zero_grad()
        total.backward()
        opt.step()
        sched.step()
        step += 1
        if step % 50 == 0 or step == cfg.steps:
            rate = 50 * cfg.batch / (time.perf_counter() - t0)
            t0 = time.perf_counter()
            print(
                f"step {step}: "
                + " ".join(f"{k} {v.item():.3f}" for k, v in losses.items())
                + f" ({rate:.0f} frames/s)",
                flush=True,
            )
        out_of_time = time_limit is not None and time.perf_counter() - t_start > time_limit
        if step % 250 == 0 or step == cfg.steps or out_of_time:
            save(model, opt, cfg, step, checkpoint, commit, where)
        if out_of_time:
            print(f"--time-limit {time_limit:g} s: stopped at step {step} of {cfg.steps}", flush=True)
            break
    return model.cpu()


def save(model, opt, cfg: JointConfig, step: int, path: Path, commit: str | None, device: str = "cpu") -> None:
    tmp = path.with_suffix(".tmp")
    state = {"model": model.state_dict(), "optimizer": opt.state_dict(), "config": asdict(cfg), "step": step}
    torch.save({**state, "git_commit": commit, "device": device}, tmp)
    tmp.replace(path)


def load(path: Path) -> tuple[JointNet, JointConfig]:
    ck = torch.load(path, map_location="cpu", weights_only=False)
    cfg = JointConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in ck["config"].items()})
    model = JointNet(cfg)
    model.load_state_dict(ck["model"])
    model.eval()
    return model, cfg


def export(checkpoint: Path, package: Path) -> None:
    """Adds the JointNet of `checkpoint` to a model package."""
    model, cfg = load(checkpoint)
    ck = torch.load(checkpoint, map_location="cpu", weights_only=False)
    provenance = {
        "command": "python -m umpnet_train.joint_net",
        "steps": ck["step"],
        "git_commit": ck.get("git_commit"),
        "device": ck.get("device", "cpu"),
        "checkpoint": checkpoint.name,
    }
    export_joint(model, cfg, package, provenance)


def export_joint(model: JointNet, cfg: JointConfig, package: Path, provenance: dict | None = None) -> None:
    """Writes `joint.onnx` into a model package (its input size must match),
    checked against PyTorch, and names it in model.json's `files.joint`; the
    package then grasps by `affordance_times_movable_lever`."""
    import onnxruntime as ort

    meta_path = package / "model.json"
    meta = json.loads(meta_path.read_text())
    size = (meta["input"]["height"], meta["input"]["width"])
    if size != (cfg.height, cfg.width):
        raise ValueError(f"{package}: input {size[0]}x{size[1]}, JointNet {cfg.height}x{cfg.width}")
    model.eval()
    obs = torch.zeros(1, cfg.height, cfg.width, CHANNELS)
    obs[..., 9] = 2.0
    path = package / "joint.onnx"
    torch.onnx.export(
        model,
        (obs,),
        str(path),
        input_names=["observation"],
        output_names=["joint_fields"],
        dynamic_axes={"observation": {0: "n"}, "joint_fields": {0: "n"}},
        opset_version=17,
        dynamo=False,
    )
    with torch.no_grad():
        expected = model(obs).numpy()
    got = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).run(None, {"observation": obs.numpy()})[0]
    worst = float(np.abs(expected - got).max())
    if worst > 1e-3:
        raise ValueError(f"{path}: ONNX differs from PyTorch by {worst}")
    meta["files"]["joint"] = "joint.onnx"
    # The runtime then grasps where the PositionNet and the JointNet's
    # movable mask agree, away from a hinge's axis (model.json `grasp`,
    # docs/model-package.md).
    meta["grasp"] = "affordance_times_movable_lever"
    meta["joint"] = {
        "outputs": list(OUTPUTS),
        "config": asdict(cfg),
        "provenance": provenance or {},
        "export_check": {"max_abs_diff": worst},
    }
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", type=Path, required=True, help="the run's folder (joint.pt)")
    p.add_argument("--steps", type=int, default=JointConfig.steps)
    p.add_argument("--frames", type=int, default=JointConfig.frames)
    p.add_argument("--seed", type=int, default=JointConfig.seed)
    p.add_argument("--widths", default=",".join(map(str, JointConfig.widths)), help="U-Net widths per level")
    p.add_argument("--batch", type=int, default=JointConfig.batch, help="frames per update")
    p.add_argument("--lr", type=float, default=JointConfig.lr, help="peak learning rate (cosine decay)")
    p.add_argument("--device", default="auto", help="auto (cuda when available), cpu or cuda")
    p.add_argument("--workers", type=int, default=1, help="processes making the frames (the same frames for any)")
    p.add_argument(
        "--time-limit",
        type=float,
        metavar="SECONDS",
        help="stop after the step that passes SECONDS, with a checkpoint --resume continues",
    )
    p.add_argument("--resume", action="store_true", help="continue OUT/joint.pt")
    p.add_argument("--color-jitter", action="store_true", help="jitter each training image's colours")
    p.add_argument("--mirror", type=float, default=0.0, help="share of each batch's frames mirrored left-right")
    p.add_argument("--export", type=Path, metavar="PACKAGE", help="add OUT/joint.pt to this package, no training")
    a = p.parse_args(argv)
    try:
        widths = tuple(int(w) for w in a.widths.split(","))
    except ValueError:
        widths = ()
    if not widths or min(widths) <= 0:
        p.error(f"--widths {a.widths}: expected positive integers, e.g. 16,32,64,128")
    if a.steps <= 0 or a.batch <= 0 or a.frames < a.batch:
        p.error("--steps and --batch must be positive and --frames at least one batch")
    if not a.lr > 0 or a.workers < 1 or (a.time_limit is not None and not a.time_limit > 0):
        p.error("--lr and --time-limit must be positive and --workers at least 1")
    if not 0 <= a.mirror <= 1:
        p.error(f"--mirror {a.mirror}: expected a share between 0 and 1")
    if a.device not in ("auto", "cpu", "cuda"):
        p.error(f"--device {a.device}: expected auto, cpu or cuda")
    device = "cuda" if a.device == "auto" and torch.cuda.is_available() else a.device.replace("auto", "cpu")
    try:
        if a.export:
            export(a.out / "joint.pt", a.export)
            return 0
        cfg = JointConfig(
            steps=a.steps,
            frames=a.frames,
            seed=a.seed,
            color_jitter=a.color_jitter,
            widths=widths,
            batch=a.batch,
            lr=a.lr,
            mirror=a.mirror,
        )
        train(cfg, a.out, a.resume, device, a.workers, a.time_limit)
    except (OSError, ValueError, KeyError) as e:
        p.error(str(e))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
