"""Where a model package loses: its direction and position networks scored
against what the simulator actually does, on held-out states of both splits.

    python -m umpnet_train.diagnose ../models/umpnet-small [--episodes 40] [--json]

The package runs in the Rust runtime (umpnet.Policy), as a robot would run it.
At every state the learned policy visits, each of its CEM candidates (and the
direction it chose) is simulated on a copy of the articulation
(VecEnv.probe_directions), which gives:

- AoT accuracy: the predicted Arrow of Time of each candidate against the
  true one, relative to the reference image's state (the start when exploring,
  the goal in the goal task), with the training labels' thresholds; with the
  confusion of the three classes, the balanced accuracy (the mean of their
  recalls, which calling more candidates still cannot raise), and the sign's
  accuracy where the part moved past delta and the head said it would;
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
Every figure is also given per category (`by_category` in the JSON;
`--by-category` prints it); `--categories A,B` runs only those.

By default each decision is the networks' own at that state alone (the
paper's policy, no memory). `--explore-filter F` / `--goal-filter F` decide as
`umpnet eval --direction-filter F` does instead: one runtime policy per
environment, with the episode's memory (stalled moves, how the gripper went,
the joint read at the grasp), so the progress share and success are those of
the policy as it runs. A filter rewrites what the heads said of the candidates
it rules on, so those runs do not score AoT accuracy or distance ranks.
`--mirror-average` scores every candidate as `umpnet eval --mirror-average`
does, on the scene and on its mirror image, and the heads' figures are those
of the mean.
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
# The runtime's direction filters that serve each task (`umpnet explore --help`).
EXPLORE_FILTERS = ("none", "normal90", "prev90", "joint45", "onward45")
GOAL_FILTERS = ("none", "normal90", "joint45", "goal45")


@dataclass
class Tally:
    """What one run of episodes measured."""

    states: int = 0
    rhos: list[float] = field(default_factory=list)
    # One row per episode (PER_EPISODE), and its category.
    rows: list[np.ndarray] = field(default_factory=list)
    categories: list[str] = field(default_factory=list)
    # Per category, AoT truth (rows) against prediction (columns), classes -1, 0, +1.
    confusions: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def episodes(self) -> int:
        return len(self.rows)

    def count(self, category: str, truth: np.ndarray, predicted: np.ndarray) -> None:
        c = self.confusions.setdefault(category, np.zeros((3, 3), np.int64))
        np.add.at(c, (truth + 1, predicted + 1), 1)

    def summary(self) -> dict:
        rows = np.array(self.rows).reshape(-1, len(PER_EPISODE))
        confusion = sum(self.confusions.values(), np.zeros((3, 3), np.int64))
        out = figures(rows, confusion)
        out["rank_correlation"] = float(np.median(self.rhos)) if self.rhos else None
        out["states"] = self.states
        cats = np.array(self.categories)
        out["by_category"] = {
            c: figures(rows[cats == c], self.confusions.get(c, np.zeros((3, 3), np.int64)))
            for c in dict.fromkeys(self.categories)
        }
        return out


PER_EPISODE = ("aot_hits", "aot_total", "chosen_progress", "best_progress", "valid_position", "success")


def figures(rows: np.ndarray, confusion: np.ndarray) -> dict:
    """The figures of some episodes (rows of PER_EPISODE) and their AoT confusion."""

    def share(a, b):
        return float(a / b) if b else None

    hits, total, chosen, best, valid, success = rows.sum(0) if len(rows) else np.zeros(len(PER_EPISODE))
    truths = confusion.sum(1)
    recalls = [confusion[k, k] / truths[k] for k in range(3) if truths[k]]
    return {
        "episodes": len(rows),
        "position_validity": share(valid, len(rows)),
        "success": share(success, len(rows)),
        "aot_accuracy": share(hits, total),
        "aot_accuracy_95": ratio_interval(rows[:, 0], rows[:, 1]),
        # The mean of the three classes' recalls: unlike the accuracy, a head
        # cannot raise it by calling more candidates still (the commonest class).
        "aot_balanced_accuracy": float(np.mean(recalls)) if recalls else None,
        "aot_confusion": confusion.tolist() if confusion.any() else None,
        # Of the candidates that moved the part past delta and were predicted
        # to: how often the arrow's sign was right.
        "aot_sign_accuracy": share(
            int(confusion[0, 0] + confusion[2, 2]), int(confusion[np.ix_([0, 2], [0, 2])].sum())
        ),
        "progress_share": share(chosen, best),
        "progress_share_95": ratio_interval(rows[:, 2], rows[:, 3]),
    }


def ratio_interval(num: np.ndarray, den: np.ndarray, resamples: int = 2000) -> list[float] | None:
    """A 95% bootstrap interval of sum(num) / sum(den), resampling episodes
    (the states of one episode are not independent); None with no denominator.
    Seeded: the same rows give the same interval."""
    if len(den) == 0 or den.sum() <= 0:
        return None
    rng = np.random.default_rng(0)
    pick = rng.integers(len(den), size=(resamples, len(den)))
    n, d = num[pick].sum(1), den[pick].sum(1)
    r = n[d > 0] / d[d > 0]
    return [float(np.quantile(r, 0.025)), float(np.quantile(r, 0.975))]


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


class Episodes:
    """One runtime policy per environment, each deciding with its episode's
    memory as `umpnet eval` does (`Policy.decide`): moves that stalled are not
    tried again, and the direction filter reads the joint at the grasp and how
    the gripper went."""

    def __init__(
        self, package: Path, n: int, seed: int, direction_filter: str, threads: int = 1, mirror_average: bool = False
    ):
        self.policies = [
            umpnet.Policy(
                str(package),
                seed=seed,
                threads=threads,
                direction_filter=direction_filter,
                mirror_average=mirror_average,
            )
            for _ in range(n)
        ]
        self.stream = np.random.default_rng(seed)

    def start(self) -> None:
        for p in self.policies:
            p.reset(seed=int(self.stream.integers(2**63)))

    def decide(self, obs, live, mode, moved, gripper):
        """The live environments' decisions; a stop for the rest."""
        out = []
        for i, p in enumerate(self.policies):
            if not live[i]:
                out.append({"direction": None, "candidates": [], "distance": [], "aot": []})
                continue
            pixel = tuple(int(v) for v in obs["gripper_pixel"][i])
            out.append(
                p.decide(
                    obs["image"][i],
                    obs["reference"][i],
                    pixel,
                    mode,
                    None if moved is None else bool(moved[i]),
                    [float(v) for v in gripper[i]] if np.isfinite(gripper[i]).all() else None,
                )
            )
        return out


def episode_setup(scenes, joint, task):
    """Per environment, from its scene and the joint its grasp holds (-1 for
    none): the joint's start value, its goal value (NaN unless `task` is goal)
    and the category's move budget."""
    start = np.array([s["joints"][j] if j >= 0 else 0.0 for s, j in zip(scenes, joint, strict=True)])
    goal = np.array(
        [s["goal"]["joints"][j] if task == "goal" and j >= 0 else np.nan for s, j in zip(scenes, joint, strict=True)]
    )
    budget = np.array([BUDGETS[s["category"]] for s in scenes])
    return start, goal, budget


def run(
    policy,
    split,
    task,
    episodes,
    seed,
    physics,
    position="learned",
    direction="learned",
    probe=True,
    n=8,
    memory=None,
    categories=None,
):
    """Episodes of `task` on `split`'s categories (or those of them in
    `categories`); `position`/`direction` are
    "learned" or "oracle". Probing (the direction diagnostics) runs only where
    the learned directions act. `memory` (an [`Episodes`] of n policies) makes
    the learned decisions as `umpnet eval` does, under its direction filter;
    without it each is the networks' own choice at that state alone, and
    only then are the heads' Arrow of Time and distance ranks scored (a
    filter overrides what the heads said of the candidates it rules on)."""
    env = umpnet.VecEnv(
        n,
        category=categories or SPLITS[split],
        split=split,
        seed=seed,
        resolution=policy.resolution,
        task=task,
        physics=physics,
    )
    mode = "goal" if task == "goal" else "explore"
    tally = Tally()
    while tally.episodes < episodes:
        obs = env.reset()
        scenes = env.scenes
        if memory is not None:
            memory.start()
        take = min(n, episodes - tally.episodes)  # the last batch may run more than it counts
        acc = np.zeros((n, len(PER_EPISODE)))
        if position == "learned":
            pixels = []
            for i in range(n):
                image, goal_image = obs["image"][i], obs["reference"][i] if task == "goal" else None
                chooser = policy if memory is None else memory.policies[i]
                pixels.append(chooser.position(image, goal_image))
        else:
            pixels = env.scripted_actions("oracle")
        obs, info = env.step_position(np.array(pixels, np.int64))
        gripper, moved = np.asarray(info["gripper_in_world"]), None
        joint = np.array(info["joint"])
        valid = np.array(info["valid"], bool)
        thr = np.asarray(info["threshold"], np.float64)
        lower, upper = np.asarray(info["limits"], np.float64).T
        start, goal, budget = episode_setup(scenes, joint, task)
        value = start.copy()
        live = valid.copy()
        success = np.zeros(n, bool)
        for t in range(int(budget.max())):
            live &= t < budget
            if not live.any():
                break
            if direction == "learned":
                # An environment without a grasp reports pixel (-1, -1); its
                # answer is not used (it is not live), but the pixel must be on the image.
                if memory is None:
                    pixels = np.maximum(obs["gripper_pixel"], 0)
                    res = policy.direction_batch(obs["image"], obs["reference"], pixels, mode)
                else:
                    res = memory.decide(obs, live, mode, moved, gripper)
                dirs = np.array([r["direction"] or [0.0, 0.0, 1.0] for r in res], np.float32)
                live &= np.array([r["direction"] is not None for r in res])
                if probe and live.any():
                    counted = live & (np.arange(n) < take)
                    measure(env, res, dirs, counted, value, start, goal, task, tally, acc, scenes, memory is None)
            else:
                dirs = np.array(
                    [d if isinstance(d, list) else [0.0, 0.0, 1.0] for d in env.scripted_actions("oracle")], np.float32
                )
            before = value.copy()
            obs, labels, sinfo = env.step_direction(dirs)
            moved, gripper = np.asarray(labels["moved"]), np.asarray(sinfo["gripper_in_world"])
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
        acc[:, 4], acc[:, 5] = valid, success
        tally.rows.extend(acc[:take])
        tally.categories.extend(s["category"] for s in scenes[:take])
    return tally


def measure(env, res, dirs, live, value, start, goal, task, tally, acc, scenes, heads=True):
    """Simulates every candidate and the chosen direction at the `live`
    states, adding to each episode's row of `acc` (PER_EPISODE); `heads`:
    also score the heads' Arrow of Time and distance ranks."""
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
        if heads:
            truth = true_aot(value[i], after[:m], ref, labels["train_moved"][i, :m])
            pred = np.asarray(res[i]["aot"])
            acc[i, 0] += int((pred == truth).sum())
            acc[i, 1] += m
            tally.count(scenes[i]["category"], truth, pred)
            rho = spearman(np.asarray(res[i]["distance"], np.float64), labels["r_dist"][i, :m].astype(np.float64))
            if rho is not None:
                tally.rhos.append(rho)
        tally.states += 1
        gain = progress(value[i], after, start[i], goal[i], task)
        acc[i, 2] += float(gain[m])
        acc[i, 3] += float(max(gain.max(), 0.0))


def unknown_category(categories: list[str] | None) -> str | None:
    """What is wrong with the first name that is no benchmark category, if any."""
    known = SPLITS["train"] + SPLITS["test"]
    for c in categories or []:
        if c not in known:
            return f"category {c!r}: expected one of {', '.join(known)}"
    return None


def diagnose(
    package: Path,
    episodes: int,
    seed: int,
    physics: str,
    threads: int = 1,
    filters: dict | None = None,
    mirror_average: bool = False,
    categories: list[str] | None = None,
) -> dict:
    """`categories` limits the run to those categories (a split with none of
    them is left out of the report). `filters` maps a task ("exploration", "goal") to the direction filter
    its learned decisions run under, with the episode's memory, as `umpnet
    eval --direction-filter` runs them; a task not in it gets the networks'
    stateless choice (the paper's policy). With `mirror_average` every
    candidate's scores are the mean over the scene and its mirror image, as
    `umpnet eval --mirror-average` scores them."""
    filters = filters or {}
    if (bad := unknown_category(categories)) is not None:
        raise ValueError(bad)
    policy = umpnet.Policy(str(package), seed=seed, threads=threads, mirror_average=mirror_average)
    report = {
        "package": str(package),
        "episodes": episodes,
        "seed": seed,
        "physics": physics,
        "filters": filters,
        "mirror_average": mirror_average,
        "categories": categories,
        "splits": {},
    }

    def memory(task, s):
        f = filters.get(task)
        return None if f is None else Episodes(package, 8, s, f, threads, mirror_average)

    for split in ("train", "test"):
        cats = [c for c in SPLITS[split] if categories is None or c in categories]
        if not cats:
            continue
        s = SEED_OFFSET + seed * 1000 + (0 if split == "train" else 500)

        on = {"categories": cats}
        explore = run(policy, split, "exploration", episodes, s, physics, memory=memory("exploration", s), **on)
        explore = explore.summary()
        goal = run(policy, split, "goal", episodes, s + 1, physics, memory=memory("goal", s + 1), **on).summary()
        swap = {
            "learned/learned": goal["success"],
            "learned/oracle": run(policy, split, "goal", episodes, s + 1, physics, direction="oracle", **on).summary()[
                "success"
            ],
            "oracle/learned": run(
                policy, split, "goal", episodes, s + 1, physics, position="oracle", memory=memory("goal", s + 1), **on
            ).summary()["success"],
        }
        report["splits"][split] = {"exploration": explore, "goal": goal, "swap": swap}
    return report


def fmt(v, interval=None):
    if v is None:
        return "-"
    return f"{v:.2f}" + ("" if interval is None else f" [{interval[0]:.2f}, {interval[1]:.2f}]")


def print_by_category(r: dict) -> None:
    """Per category of each split: where the heads and the policy lose."""
    head = ("episodes", "AoT acc", "balanced", "chosen/best", "success")
    for split, tasks in r["splits"].items():
        for task in ("exploration", "goal"):
            print(f"\n{split} categories, {task}")
            print(f"{'category':18} " + " ".join(f"{h:>11}" for h in head))
            for cat, f in tasks[task]["by_category"].items():
                keys = ("aot_accuracy", "aot_balanced_accuracy", "progress_share", "success")
                print(f"{cat:18} {f['episodes']:>11} " + " ".join(f"{fmt(f[k]):>11}" for k in keys))


def print_report(r: dict) -> None:
    print(f"{r['package']}: {r['episodes']} episodes per split and task, seed {r['seed']}, {r['physics']} physics")
    for task, f in r.get("filters", {}).items():
        print(f"{task}: decided as `umpnet eval --direction-filter {f}` does (heads' AoT and ranks not scored)")
    rows = [
        ("AoT accuracy (exploration)", "exploration", "aot_accuracy"),
        ("AoT accuracy (goal)", "goal", "aot_accuracy"),
        ("AoT balanced accuracy (exploration)", "exploration", "aot_balanced_accuracy"),
        ("AoT balanced accuracy (goal)", "goal", "aot_balanced_accuracy"),
        ("AoT sign, moved and predicted to (exploration)", "exploration", "aot_sign_accuracy"),
        ("AoT sign, moved and predicted to (goal)", "goal", "aot_sign_accuracy"),
        ("distance rank correlation (exploration)", "exploration", "rank_correlation"),
        ("distance rank correlation (goal)", "goal", "rank_correlation"),
        ("chosen / best progress (exploration)", "exploration", "progress_share"),
        ("chosen / best progress (goal)", "goal", "progress_share"),
        ("position validity (exploration)", "exploration", "position_validity"),
        ("position validity (goal)", "goal", "position_validity"),
    ]
    splits = list(r["splits"])
    if r.get("categories"):
        print(f"categories: {', '.join(r['categories'])}")
    print(f"{'diagnostic (95% interval over episodes)':48} " + " ".join(f"{s:>18}" for s in splits))
    for name, task, key in rows:
        cells = (fmt(r["splits"][s][task][key], r["splits"][s][task].get(key + "_95")) for s in splits)
        print(f"{name:48} " + " ".join(f"{c:>18}" for c in cells))
    print(f"\n{'goal success: position / direction':48} " + " ".join(f"{s:>18}" for s in splits))
    for combo in ("learned/learned", "learned/oracle", "oracle/learned"):
        print(f"{combo:48} " + " ".join(f"{fmt(r['splits'][s]['swap'][combo]):>18}" for s in splits))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("package", type=Path, help="a model package directory (model.json + ONNX files)")
    p.add_argument("--episodes", type=int, default=40, help="episodes per split, task and swap (default 40)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--physics", choices=["reference", "ideal"], default="reference")
    p.add_argument("--threads", type=int, default=1, help="runtime threads")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument(
        "--explore-filter",
        choices=EXPLORE_FILTERS,
        help="decide exploring as `umpnet eval --direction-filter FILTER` does, with the episode's memory "
        "(e.g. onward45); the chosen direction's progress is then the policy's, not the networks' alone",
    )
    p.add_argument(
        "--goal-filter", choices=GOAL_FILTERS, help="the same toward a goal (e.g. goal45), in the swap table too"
    )
    p.add_argument(
        "--mirror-average",
        action="store_true",
        help="score every candidate also on the scene mirrored left-right and use the mean, as "
        "`umpnet eval --mirror-average` does (beyond the paper)",
    )
    p.add_argument(
        "--categories",
        help="only these categories, comma-separated (e.g. Bucket,Dishwasher): more episodes where a model loses",
    )
    p.add_argument(
        "--by-category", action="store_true", help="also print the figures per category (the JSON always has them)"
    )
    a = p.parse_args(argv)
    if a.episodes < 1:
        p.error(f"--episodes {a.episodes}: expected at least 1")
    categories = [c.strip() for c in a.categories.split(",") if c.strip()] if a.categories else None
    if (bad := unknown_category(categories)) is not None:
        p.error(f"--categories: {bad}")
    if not (a.package / "model.json").is_file():
        print(f"error: {a.package}: no model.json (expected a model package directory)", file=sys.stderr)
        return 2
    try:
        filters = {t: f for t, f in (("exploration", a.explore_filter), ("goal", a.goal_filter)) if f}
        report = diagnose(a.package, a.episodes, a.seed, a.physics, a.threads, filters, a.mirror_average, categories)
    except (ValueError, RuntimeError) as e:
        print(f"error: {a.package}: {e}", file=sys.stderr)
        return 2
    if a.json:
        print(json.dumps(report, indent=2))
    else:
        print_report(report)
        if a.by_category:
            print_by_category(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
