"""Where a model package loses: its direction and position networks scored
against what the simulator actually does, on held-out states of both splits.

    python -m umpnet_train.diagnose ../models/umpnet-small [--episodes 40] [--json]

The package runs in the Rust runtime (umpnet.Policy), as a robot would run it.
At every state the learned policy visits, each of its CEM candidates (and the
direction it chose) is simulated on a copy of the articulation
(VecEnv.probe_directions), which gives:

- AoT accuracy: the predicted Arrow of Time of each candidate against the
  true one, relative to the reference image's state (the start when exploring,
  the goal in the goal task), with the training labels' thresholds;
- rank correlation: Spearman's rho of predicted against true distance over one
  state's candidates (median over states);
- progress share: the chosen direction's progress (away from the start when
  exploring, toward the goal in the goal task) as a share of the best
  candidate's, summed over states;
- position validity: the share of the position network's pixels that land on
  a part that can move (the goal's part in the goal task);
- the swap table: goal success with either half of the policy replaced by the
  privileged oracle.

Held-out: the scenes come from seeds training never uses (see SEED_OFFSET).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import umpnet

from .collect import TRAIN_CATEGORIES

TEST_CATEGORIES = [name for name, split, _ in umpnet.categories() if split == "test"]
BUDGETS = {name: budget for name, _, budget in umpnet.categories()}
# Training environments take seeds seed*1000 + epoch + i; these never collide.
SEED_OFFSET = 7_000_000
SPLITS = {"train": TRAIN_CATEGORIES, "test": TEST_CATEGORIES}


@dataclass
class Tally:
    """What one run of episodes measured."""

    episodes: int = 0
    valid_positions: int = 0
    successes: int = 0
    aot_hits: int = 0
    aot_total: int = 0
    rhos: list[float] = field(default_factory=list)
    chosen_progress: float = 0.0
    best_progress: float = 0.0

    def summary(self) -> dict:
        def share(a, b):
            return a / b if b else None

        return {
            "episodes": self.episodes,
            "position_validity": share(self.valid_positions, self.episodes),
            "success": share(self.successes, self.episodes),
            "aot_accuracy": share(self.aot_hits, self.aot_total),
            "rank_correlation": float(np.median(self.rhos)) if self.rhos else None,
            "progress_share": share(self.chosen_progress, self.best_progress),
            "states": len(self.rhos),
        }


def spearman(a: np.ndarray, b: np.ndarray) -> float | None:
    """Spearman's rho (average ranks for ties); None when either side is constant."""

    def ranks(x):
        order = np.argsort(x, kind="stable")
        r = np.empty(len(x))
        r[order] = np.arange(len(x))
        for v in np.unique(x):  # ties share their mean rank
            tie = x == v
            r[tie] = r[tie].mean()
        return r

    ra, rb = ranks(a), ranks(b)
    if ra.std() < 1e-12 or rb.std() < 1e-12:
        return None
    return float(np.corrcoef(ra, rb)[0, 1])


def true_aot(before, after, reference, moved):
    """The Arrow of Time of a move relative to the reference state: -1 toward it, +1 away, 0 not moved."""
    toward = (after - before) * (before - reference) < 0
    return np.where(moved, np.where(toward, -1, 1), 0)


def progress(before, after, start, goal, task):
    if task == "goal":
        return np.abs(before - goal) - np.abs(after - goal)
    return np.abs(after - start) - np.abs(before - start)


def run(policy, split, task, episodes, seed, physics, position="learned", direction="learned", probe=True, n=8):
    """Episodes of `task` on `split`'s categories; `position`/`direction` are
    "learned" or "oracle". Probing (the direction diagnostics) runs only where
    the learned directions act."""
    env = umpnet.VecEnv(
        n, category=SPLITS[split], split=split, seed=seed, resolution=policy.resolution, task=task, physics=physics
    )
    mode = "goal" if task == "goal" else "explore"
    tally = Tally()
    while tally.episodes < episodes:
        obs = env.reset()
        scenes = env.scenes
        if position == "learned":
            pixels = [
                policy.position(obs["image"][i], obs["reference"][i] if task == "goal" else None) for i in range(n)
            ]
        else:
            pixels = env.scripted_actions("oracle")
        obs, info = env.step_position(np.array(pixels, np.int64))
        joint = np.array(info["joint"])
        valid = np.array(info["valid"], bool)
        thr = np.asarray(info["threshold"], np.float64)
        lower, upper = np.asarray(info["limits"], np.float64).T
        start = np.array([s["joints"][j] if j >= 0 else 0.0 for s, j in zip(scenes, joint, strict=True)])
        goal = np.array(
            [
                s["goal"]["joints"][j] if task == "goal" and j >= 0 else np.nan
                for s, j in zip(scenes, joint, strict=True)
            ]
        )
        value = start.copy()
        budget = np.array([BUDGETS[s["category"]] for s in scenes])
        live = valid.copy()
        success = np.zeros(n, bool)
        for t in range(int(budget.max())):
            live &= t < budget
            if not live.any():
                break
            if direction == "learned":
                # An environment without a grasp reports pixel (-1, -1); its
                # answer is not used (it is not live), but the pixel must be on the image.
                pixels = np.maximum(obs["gripper_pixel"], 0)
                res = policy.direction_batch(obs["image"], obs["reference"], pixels, mode)
                dirs = np.array([r["direction"] or [0.0, 0.0, 1.0] for r in res], np.float32)
                live &= np.array([r["direction"] is not None for r in res])
                if probe and live.any():
                    measure(env, res, dirs, live, value, start, goal, task, tally)
            else:
                dirs = np.array(
                    [d if isinstance(d, list) else [0.0, 0.0, 1.0] for d in env.scripted_actions("oracle")], np.float32
                )
            before = value.copy()
            obs, _, sinfo = env.step_direction(dirs)
            after = np.asarray(sinfo["joint_after"], np.float64)
            value = np.where(live, after, value)
            if task == "goal":
                reached = (
                    (np.abs(after - goal) < thr)
                    | ((before > goal) & (after < goal + thr))
                    | ((before < goal) & (after > goal - thr))
                )
            else:
                reached = (np.abs(after - start) > thr) & ((after < lower + thr) | (after > upper - thr))
            success |= live & reached
            live &= ~reached
        take = min(n, episodes - tally.episodes)
        tally.episodes += take
        tally.valid_positions += int(valid[:take].sum())
        tally.successes += int(success[:take].sum())
    return tally


def measure(env, res, dirs, live, value, start, goal, task, tally):
    """Simulates every candidate and the chosen direction at the current states."""
    k = max(len(r["candidates"]) for r in res)
    cand = np.zeros((len(res), k + 1, 3), np.float32)
    for i, r in enumerate(res):
        c = np.asarray(r["candidates"], np.float32).reshape(-1, 3)
        cand[i, : len(c)] = c
        cand[i, len(c) :] = dirs[i]  # padding repeats the chosen direction, counted once below
    labels = env.probe_directions(cand)
    for i in np.flatnonzero(live & np.asarray(labels["active"])):
        m = len(res[i]["candidates"])
        after = labels["joint_after"][i].astype(np.float64)
        ref = goal[i] if task == "goal" else start[i]
        truth = true_aot(value[i], after[:m], ref, labels["train_moved"][i, :m])
        pred = np.asarray(res[i]["aot"])
        tally.aot_hits += int((pred == truth).sum())
        tally.aot_total += m
        rho = spearman(np.asarray(res[i]["distance"], np.float64), labels["r_dist"][i, :m].astype(np.float64))
        if rho is not None:
            tally.rhos.append(rho)
        gain = progress(value[i], after, start[i], goal[i], task)
        tally.chosen_progress += float(gain[m])
        tally.best_progress += float(max(gain.max(), 0.0))


def diagnose(package: Path, episodes: int, seed: int, physics: str, threads: int = 1) -> dict:
    policy = umpnet.Policy(str(package), seed=seed, threads=threads)
    report = {"package": str(package), "episodes": episodes, "seed": seed, "physics": physics, "splits": {}}
    for split in ("train", "test"):
        s = SEED_OFFSET + seed * 1000 + (0 if split == "train" else 500)
        explore = run(policy, split, "exploration", episodes, s, physics).summary()
        goal = run(policy, split, "goal", episodes, s + 1, physics).summary()
        swap = {
            "learned/learned": goal["success"],
            "learned/oracle": run(policy, split, "goal", episodes, s + 1, physics, direction="oracle").summary()[
                "success"
            ],
            "oracle/learned": run(policy, split, "goal", episodes, s + 1, physics, position="oracle").summary()[
                "success"
            ],
        }
        report["splits"][split] = {"exploration": explore, "goal": goal, "swap": swap}
    return report


def fmt(v):
    return "-" if v is None else f"{v:.2f}"


def print_report(r: dict) -> None:
    print(f"{r['package']}: {r['episodes']} episodes per split and task, seed {r['seed']}, {r['physics']} physics")
    rows = [
        ("AoT accuracy (exploration)", "exploration", "aot_accuracy"),
        ("AoT accuracy (goal)", "goal", "aot_accuracy"),
        ("distance rank correlation (exploration)", "exploration", "rank_correlation"),
        ("distance rank correlation (goal)", "goal", "rank_correlation"),
        ("chosen / best progress (exploration)", "exploration", "progress_share"),
        ("chosen / best progress (goal)", "goal", "progress_share"),
        ("position validity (exploration)", "exploration", "position_validity"),
        ("position validity (goal)", "goal", "position_validity"),
    ]
    print(f"{'diagnostic':44} {'train':>6} {'test':>6}")
    for name, task, key in rows:
        print(f"{name:44} " + " ".join(f"{fmt(r['splits'][s][task][key]):>6}" for s in ("train", "test")))
    print(f"\n{'goal success: position / direction':44} {'train':>6} {'test':>6}")
    for combo in ("learned/learned", "learned/oracle", "oracle/learned"):
        print(f"{combo:44} " + " ".join(f"{fmt(r['splits'][s]['swap'][combo]):>6}" for s in ("train", "test")))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("package", type=Path, help="a model package directory (model.json + ONNX files)")
    p.add_argument("--episodes", type=int, default=40, help="episodes per split, task and swap (default 40)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--physics", choices=["reference", "ideal"], default="reference")
    p.add_argument("--threads", type=int, default=1, help="runtime threads")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    a = p.parse_args(argv)
    if a.episodes < 1:
        p.error(f"--episodes {a.episodes}: expected at least 1")
    if not (a.package / "model.json").is_file():
        print(f"error: {a.package}: no model.json (expected a model package directory)", file=sys.stderr)
        return 2
    try:
        report = diagnose(a.package, a.episodes, a.seed, a.physics, a.threads)
    except (ValueError, RuntimeError) as e:
        print(f"error: {a.package}: {e}", file=sys.stderr)
        return 2
    if a.json:
        print(json.dumps(report, indent=2))
    else:
        print_report(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
