"""How training gathers its data from the umpnet Rust environments, the
paper's way: epsilon-greedy grasps and directions after a random warm-up, the
released code's random-grasp rule, the contradictory policy (forward until the
joint limit or half the sequence, then back to the start), a growing sequence
length, and, with dense labels, K more simulated directions at each visited
state. train.py learns from what this module puts in the replay buffers."""

from __future__ import annotations

import time

import numpy as np
import torch
import umpnet

from .config import Config

FLOOR_CLEARANCE = 0.005  # m: the released code's "above the floor" for random grasps
# The categories training sees, in the paper's order (defined once, in Rust).
TRAIN_CATEGORIES = [name for name, split, _ in umpnet.categories() if split == "train"]


def epsilon(schedule: tuple[float, float], start_epoch: int, decay_epochs: int, epoch: int) -> float:
    """1 (random actions) until `start_epoch`, then linear from schedule[0] to
    schedule[1] over `decay_epochs` (the reference's warm-up and decay)."""
    if epoch < start_epoch:
        return 1.0
    first, last = schedule
    done = (epoch - start_epoch) / max(decay_epochs, 1)
    return last if done >= 1 else first + (last - first) * done


def sequence_length(cfg: Config, epoch: int) -> int:
    if epoch < cfg.seq_after:
        return cfg.seq_start
    return min(cfg.seq_max, cfg.seq_start + cfg.seq_step * (1 + (epoch - cfg.seq_after) // cfg.seq_every))


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True).clip(1e-8)


DEVICE = torch.device("cpu")


def set_device(where: torch.device) -> None:
    """Where to_torch and to_long put their tensors: the training device."""
    global DEVICE
    DEVICE = where


def device() -> torch.device:
    return DEVICE


def to_torch(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32)).to(DEVICE)


def to_long(x: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(x, dtype=np.int64)).to(DEVICE)


def random_pixel(image: np.ndarray, rng: np.random.Generator) -> int:
    """The released code's exploratory grasp: a uniformly random pixel, kept if
    its point is above the floor (z > 5 mm), else kept with probability 0.1.
    The floor pixels it keeps are the position net's negatives on the floor."""
    z = image[..., 2].ravel()
    for _ in range(10_000):
        k = int(rng.integers(z.size))
        if z[k] > FLOOR_CLEARANCE or rng.random() < 0.1:
            return k
    return int(rng.integers(z.size))  # unreachable in practice: 0.9**10000


OBJECT_SEGMENT = 1 << 16  # segment ids of object links start here


def random_object_pixel(obs, i, rng):
    """A uniform pixel on the object, or None when none is in view."""
    mask = np.flatnonzero(obs["segmentation"][i].ravel() >= OBJECT_SEGMENT)
    return int(rng.choice(mask)) if len(mask) else None


@torch.no_grad()
def choose_positions(model, obs, eps, rng, rule="released"):
    """Greedy: best affordance among pixels with depth; with probability `eps`
    (or when nothing has depth) a random pixel by the released code's rule."""
    n, _, w, _ = obs["image"].shape
    prob = torch.softmax(model.position(to_torch(obs["image"])), dim=1)[:, 1].cpu().numpy()
    prob[obs["image"][..., 9] <= 0] = -1.0
    pixels = np.zeros((n, 2), np.int64)
    for i in range(n):
        if rng.random() < eps or prob[i].max() < 0:
            k = random_object_pixel(obs, i, rng) if rule == "object" else None
            if k is None:
                k = random_pixel(obs["image"][i], rng)
        else:
            k = int(prob[i].argmax())
        pixels[i] = divmod(int(k), w)
    return pixels


_DATA_POLICIES: dict[str, umpnet.Policy] = {}


def data_policy(package: str, resolution: tuple[int, int], seed: int) -> umpnet.Policy:
    """The Rust policy of `package` (loaded once per run), which makes the
    Inverse baseline's collected moves."""
    if package not in _DATA_POLICIES:
        policy = umpnet.Policy(package, seed=seed)
        if tuple(policy.resolution) != tuple(resolution):
            raise ValueError(
                f"inverse_data {package}: the package takes {policy.resolution}, the run observes {resolution}"
            )
        _DATA_POLICIES[package] = policy
    return _DATA_POLICIES[package]


def policy_directions(policy, obs, wanted, eps, rng, out):
    """The data policy's moves, epsilon-greedy: toward the start (its goal
    mode, the reference being the first observation) where the
    contradictory policy wants to go back, away from it otherwise; a random
    move where it stops or epsilon says so."""
    pixels = obs["gripper_pixel"].clip(min=0)
    for mode, rows in (("goal", np.flatnonzero(wanted == -1)), ("explore", np.flatnonzero(wanted != -1))):
        if len(rows) == 0:
            continue
        decisions = policy.direction_batch(obs["image"][rows], obs["reference"][rows], pixels[rows], mode)
        for i, d in zip(rows, decisions, strict=True):
            if d["direction"] is not None and rng.random() >= eps:
                out[i] = d["direction"]
    return out


@torch.no_grad()
def choose_directions(model, variant, obs, wanted, eps, rng, candidates=64, data=None):
    """Greedy: among random candidates, the largest predicted distance with the
    wanted AoT (+1 forward, -1 back, 0 either: the first step of a sequence);
    else a uniformly random direction. Returns (directions n x 3, candidates
    n x C x 3 ordered best first by the policy's score).
    The Inverse baseline has no score to explore with: its moves come from
    `data` (a trained policy, as the paper's), else uniformly at random."""
    n = obs["image"].shape[0]
    cand = unit(rng.normal(size=(n, candidates, 3))).astype(np.float32)
    out = unit(rng.normal(size=(n, 3))).astype(np.float32)
    if variant == "inverse":
        if data is not None:
            out = policy_directions(data, obs, np.asarray(wanted), eps, rng, out)
        return out, cand
    pix = to_long(obs["gripper_pixel"].clip(min=0))
    de, ae = model.encoder(to_torch(obs["image"]), to_torch(obs["reference"]), pix)
    dist, logits = model.decoder(
        de.repeat_interleave(candidates, 0), ae.repeat_interleave(candidates, 0), to_torch(cand.reshape(-1, 3))
    )
    dist = dist.view(n, candidates).cpu().numpy()
    probs = torch.softmax(logits, 1).view(n, candidates, 3).cpu().numpy()
    ranked = np.empty_like(cand)
    for i in range(n):
        w = int(wanted[i])
        k = {1: 2, -1: 0, 0: None}[w]
        if variant == "aot-only":
            score = 1.0 - probs[i, :, 1] if k is None else probs[i, :, k]
        elif variant == "where2act":
            score = dist[i]  # logit of success; no arrow of time
        elif variant == "signed-dist":
            score = np.abs(dist[i]) if k is None else dist[i] * w
        else:
            moving = probs[i].argmax(1) != 1 if k is None else probs[i].argmax(1) == k
            score = np.where(moving, dist[i], -np.inf)
        order = np.argsort(-np.nan_to_num(score, neginf=-1e30), kind="stable")
        ranked[i] = cand[i, order]
        if rng.random() >= eps and np.isfinite(score.max()):
            out[i] = cand[i, order[0]]
    return out, ranked


def contradictory_heading(heading: np.ndarray, t: int, length: int, reached_boundary: np.ndarray) -> np.ndarray:
    """The reference's contradictory policy after step `t` of a sequence of
    `length`: +1 (away from the start) turns to -1 (back) at the joint's
    boundary or after half the sequence, and stays -1."""
    turn = (heading == 1) & ((t + 1 == length // 2) | reached_boundary)
    return np.where(turn, -1, heading)


def dense_directions(ranked: np.ndarray, k: int, rng) -> np.ndarray:
    """The K directions to probe at each state: the policy's best half of its
    candidates, and uniformly random ones for the rest."""
    n = ranked.shape[0]
    best = min(k // 2, ranked.shape[1])
    rand = unit(rng.normal(size=(n, k - best, 3))).astype(np.float32)
    return np.ascontiguousarray(np.concatenate([ranked[:, :best], rand], axis=1), dtype=np.float32)


def flow_target(env, cfg):
    """The articulation flow the auxiliary heads learn, per environment (n x H x W x 3)."""
    fields = env.articulation_fields()
    if cfg.aux_flow == "scaled":
        return fields["flow"] * fields["speed"][..., None]
    return fields["flow"]


def collect(env, model, cfg, replay, dense, epoch, rng, stats):
    """One sequence per environment: a position, then up to L directions under
    the contradictory policy."""
    model.eval()
    t0 = time.perf_counter()
    obs = env.reset()
    stats["sim_s"] += time.perf_counter() - t0
    refs = [replay.add_reference(obs["reference"][i]) for i in range(len(env))]
    eps_pos = epsilon(cfg.position_epsilon, cfg.position_start_epoch, cfg.position_decay_epochs, epoch)
    eps_dir = epsilon(cfg.direction_epsilon, cfg.direction_start_epoch, cfg.direction_decay_epochs, epoch)
    pixels = choose_positions(model, obs, eps_pos, rng, cfg.random_grasp)
    # The environment's observation buffers are rewritten by every step: keep copies.
    first = obs["image"].copy()
    fields = cfg.aux_fields > 0
    first_flow = flow_target(env, cfg) if fields else None
    t0 = time.perf_counter()
    obs, info = env.step_position(pixels)
    stats["sim_s"] += time.perf_counter() - t0
    valid = np.array(info["valid"])
    reference_rule = cfg.labels == "reference"
    aot_key, moved_key = ("train_aot", "train_moved") if reference_rule else ("aot", "moved")
    moved_any = np.zeros(len(env), bool)
    done = ~valid
    heading = np.ones(len(env), np.int64)  # +1 away from the start, -1 back
    length = sequence_length(cfg, epoch)
    for t in range(length):
        if done.all():
            break
        if reference_rule:
            # The reference: the first move may go either way, then forward until
            # the joint limit (or half the sequence), then back to the start.
            wanted = np.zeros(len(env), np.int64) if t == 0 else heading
        else:
            wanted = np.full(len(env), 1 if t < (length + 1) // 2 else -1)
        data = data_policy(cfg.inverse_data, (cfg.height, cfg.width), cfg.seed) if cfg.inverse_data else None
        dirs, ranked = choose_directions(model, cfg.variant, obs, wanted, eps_dir, rng, data=data)
        before = {"image": obs["image"].copy(), "gripper_pixel": obs["gripper_pixel"].copy()}
        before_flow = flow_target(env, cfg) if fields else None
        if dense is not None:
            t0 = time.perf_counter()
            probe_dirs = dense_directions(ranked, cfg.dense_labels, rng)
            probed = env.probe_directions(probe_dirs)
            stats["probe_s"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        obs, labels, sinfo = env.step_direction(dirs)
        stats["sim_s"] += time.perf_counter() - t0
        record = np.array(sinfo["active"]) & ~done
        for i in np.flatnonzero(record):
            # The Inverse model learns (s_t, s_t+1) -> a_t: its "reference" is the next observation.
            ref = replay.add_reference(obs["image"][i]) if cfg.variant == "inverse" else refs[i]
            aot = int(labels[aot_key][i])
            flow = None if before_flow is None else before_flow[i]
            replay.add_direction(
                before["image"][i], before["gripper_pixel"][i], dirs[i], labels["r_dist"][i], aot, ref, flow
            )
            moved_any[i] |= bool(labels[moved_key][i])
            stats["aot_counts"][aot + 1] += 1
            if dense is not None and probed["active"][i]:
                dense.add(
                    before["image"][i], before["gripper_pixel"][i], probe_dirs[i],
                    probed["r_dist"][i], probed[aot_key][i], refs[i],
                )  # fmt: skip
                stats["dense_labels"] += cfg.dense_labels
        if reference_rule:
            done |= (heading == -1) & np.asarray(sinfo["reached_init"])
            heading = contradictory_heading(heading, t, length, np.asarray(sinfo["reached_boundary"]))
        stats["steps"] += int(record.sum())
    for i in range(len(env)):
        replay.add_position(
            first[i], pixels[i], int(valid[i] and moved_any[i]), None if first_flow is None else first_flow[i]
        )
    stats["positions"] += len(env)
    stats["position_success"] += int((valid & moved_any).sum())
