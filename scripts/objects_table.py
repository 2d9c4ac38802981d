"""docs/objects.md's table of objects made elsewhere, from `make eval-objects`.

    .venv/bin/python scripts/objects_table.py [--dir out] [--set external] [--per-object]

Reads DIR/SET-goal/results.json and DIR/SET-exploration/results.json
(`umpnet eval --objects data/SET`) and prints, per policy, the average
over objects of goal success, goal normalised distance, the novel-state ratio
and the share of valid grasps (exploration: the grasp landed on a movable
part), each with the half-width of its 95% interval. The interval is the
normal one of a stratified mean: every object weighs the same, its variance is
the sample variance of its episodes. With --per-object, one row per object.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

from baselines_table import episodes, stratified

# column: (task, value of an episode, higher is better)
COLUMNS = {
    "goal success": ("goal", lambda e: float(e["metrics"]["success"])),
    "goal distance": ("goal", lambda e: e["metrics"]["normalized_distance"]),
    "novel-state ratio": ("exploration", lambda e: e["metrics"]["novel_state_ratio"]),
    "valid grasps": ("exploration", lambda e: float(e["valid_position"])),
}


def load(path: Path) -> dict:
    if not path.is_file():
        sys.exit(f"error: {path} not found: run `make eval-objects` first")
    with path.open() as f:
        results = json.load(f)
    results["episodes"] = list(episodes(path))
    return results


def values(results: dict[str, dict]) -> dict:
    """(column, policy) -> (object, scene index) -> the episode's value."""
    out: dict = defaultdict(dict)
    for column, (task, get) in COLUMNS.items():
        for o in results[task]["episodes"]:
            if o.get("episode") is not None:
                out[column, o["policy"]][o["object"], o["index"]] = get(o["episode"])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--dir", type=Path, default=Path("out"))
    p.add_argument("--set", default="external", help="read DIR/SET-goal and DIR/SET-exploration")
    p.add_argument("--per-object", action="store_true", help="one row per object and policy")
    a = p.parse_args(argv)
    results = {task: load(a.dir / f"{a.set}-{task}" / "results.json") for task in ("goal", "exploration")}
    policies = results["goal"]["summary"]["policies"]
    objects = [o["name"] for o in results["goal"]["summary"]["objects"]]
    n = results["goal"]["summary"]["episodes_per_category"]
    v = values(results)
    if a.per_object:
        print(f"| object | policy | {' | '.join(COLUMNS)} |")
        print(f"|---|---|{'---|' * len(COLUMNS)}")
        for obj in objects:
            for pol in policies:
                cells = []
                for c in COLUMNS:
                    mean, half = stratified({k: x for k, x in v[c, pol].items() if k[0] == obj})
                    cells.append(f"{mean:.2f} ± {half:.2f}")
                print(f"| {obj} | {pol} | {' | '.join(cells)} |")
        return 0
    print(f"{len(objects)} objects, {n} episodes each per task; mean over objects ± 95% interval\n")
    print(f"| policy | {' | '.join(COLUMNS)} |")
    print(f"|---|{'---|' * len(COLUMNS)}")
    for pol in policies:
        cells = [f"{m:.2f} ± {h:.2f}" for m, h in (stratified(v[c, pol]) for c in COLUMNS)]
        print(f"| {pol} | {' | '.join(cells)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
