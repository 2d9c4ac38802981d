"""docs/training.md's baselines table from `make eval-baselines`' results.

    .venv/bin/python scripts/baselines_table.py [--split test] [--json]

Reads out/baselines-exploration-SPLIT/results.json and
out/baselines-goal-SPLIT/results.json and prints, per policy, the average over
categories of the novel-state ratio (exploration), goal success and goal
normalised distance, each with the half-width of its 95% interval. The
interval is the normal one of a stratified mean: every category weighs the
same, its variance is the sample variance of its episodes.

Then, for umpnet (the shipped model and umpnet-300, trained with the
baselines' budget) against every baseline on its own task, the paired
difference: the same scenes run under both policies, so the interval is on
the per-scene difference, again stratified by category. "beats" means the
whole interval is on umpnet's side.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import defaultdict
from pathlib import Path

METRICS = {
    # metric: (task, key in an episode's metrics, higher is better)
    "novel-state ratio": ("exploration", "novel_state_ratio", True),
    "goal success": ("goal", "success", True),
    "goal distance": ("goal", "normalized_distance", False),
}
UMPNETS = ("umpnet", "umpnet-300")


def load(path: Path) -> dict:
    if not path.is_file():
        sys.exit(f"error: {path} not found: run `make eval-baselines` first")
    with path.open() as f:
        results = json.load(f)
    results["episodes"] = list(episodes(path))
    return results


def episodes(results_json: Path):
    """The episodes of an `umpnet eval --out` run, one at a time, from the
    episodes file its results.json names."""
    name = json.loads(results_json.read_text()).get("episodes_file")
    if not name:
        sys.exit(f"error: {results_json} names no episodes file; run the evaluation again")
    with (results_json.parent / name).open() as f:
        for line in f:
            yield json.loads(line)


def values(results: dict, key: str) -> dict[str, dict[tuple[str, int], float]]:
    """policy -> (category, scene index) -> the episode's value of `key`."""
    out: dict[str, dict[tuple[str, int], float]] = defaultdict(dict)
    for e in results["episodes"]:
        if e.get("error") is not None:
            continue
        out[e["policy"]][(e["category"], e["index"])] = float(e["episode"]["metrics"][key])
    return out


def stratified(by_scene: dict[tuple[str, int], float]) -> tuple[float, float]:
    """The mean over categories of each category's mean, and the half-width
    of its 95% interval."""
    per_category: dict[str, list[float]] = defaultdict(list)
    for (category, _), v in by_scene.items():
        per_category[category].append(v)
    k = len(per_category)
    if k == 0:
        return math.nan, math.nan
    mean = sum(sum(v) / len(v) for v in per_category.values()) / k
    variance = 0.0
    for v in per_category.values():
        m = sum(v) / len(v)
        s2 = sum((x - m) ** 2 for x in v) / max(len(v) - 1, 1)
        variance += s2 / len(v)
    return mean, 1.96 * math.sqrt(variance) / k


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split", default="test")
    ap.add_argument("--out", default="out", type=Path)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    results = {task: load(a.out / f"baselines-{task}-{a.split}" / "results.json") for task in ("exploration", "goal")}
    table: dict[str, dict[str, tuple[float, float]]] = defaultdict(dict)
    comparisons = []
    for metric, (task, key, higher) in METRICS.items():
        by_policy = values(results[task], key)
        for policy, by_scene in by_policy.items():
            table[policy][metric] = stratified(by_scene)
        for ours in UMPNETS:
            for other in by_policy:
                if other in UMPNETS or other in ("random", "oracle") or ours not in by_policy:
                    continue
                shared = by_policy[ours].keys() & by_policy[other].keys()
                sign = 1.0 if higher else -1.0
                diff = {s: sign * (by_policy[ours][s] - by_policy[other][s]) for s in shared}
                d, half = stratified(diff)
                comparisons.append(
                    {
                        "metric": metric,
                        "umpnet": ours,
                        "baseline": other,
                        "advantage": d,
                        "ci95": half,
                        "beats": d - half > 0,
                    }
                )
    if a.json:
        print(json.dumps({"split": a.split, "table": table, "comparisons": comparisons}, indent=1))
        return
    order = list(results["goal"]["summary"]["policies"])
    order += [p for p in results["exploration"]["summary"]["policies"] if p not in order]
    print(f"| policy ({a.split} categories) | " + " | ".join(METRICS) + " |")
    print("|---|" + "---|" * len(METRICS))
    for policy in order:
        cells = []
        for metric in METRICS:
            mean, half = table[policy].get(metric, (math.nan, math.nan))
            cells.append("—" if math.isnan(mean) else f"{mean:.2f} ± {half:.2f}")
        print(f"| {policy} | " + " | ".join(cells) + " |")
    print()
    print("| umpnet | baseline | metric | umpnet's advantage (paired, 95%) | beats |")
    print("|---|---|---|---|---|")
    for c in comparisons:
        print(
            f"| {c['umpnet']} | {c['baseline']} | {c['metric']} | "
            f"{c['advantage']:+.2f} ± {c['ci95']:.2f} | {'yes' if c['beats'] else 'no'} |"
        )


if __name__ == "__main__":
    main()
