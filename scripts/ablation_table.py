"""Two policies on the same scenes: their means and the paired difference.

    .venv/bin/python scripts/ablation_table.py --base A --variant B DIR [DIR ...]

Each DIR holds the results.json of one `umpnet eval` run that listed both
policies (categories or `--objects` rows). Per run and metric of its task
(goal: success and normalised distance; exploration: novel-state ratio and
single action effect) it prints both policies' means over rows and the
variant's advantage over the base, paired by scene, each ± the half-width of
its 95% interval: the normal interval of a stratified mean, every row (a
category or an object) weighing the same. "better" means the whole interval
is on the variant's side.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

from baselines_table import episodes, stratified

# task -> (metric, key in an episode's metrics, higher is better)
METRICS = {
    "goal": [("goal success", "success", True), ("goal distance", "normalized_distance", False)],
    "exploration": [
        ("novel-state ratio", "novel_state_ratio", True),
        ("single action effect", "single_action_effect", True),
    ],
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="the policy without the change")
    ap.add_argument("--variant", required=True, help="the policy with it")
    ap.add_argument("runs", nargs="+", type=Path, help="eval --out folders")
    a = ap.parse_args(argv)
    print(f"| run | metric | {a.base} | {a.variant} | {a.variant} − {a.base} (paired) | better |")
    print("|---|---|---|---|---|---|")
    for run in a.runs:
        path = run / "results.json" if run.is_dir() else run
        if not path.is_file():
            sys.exit(f"error: {path} not found")
        results = json.loads(path.read_text())
        task = results["summary"]["task"]
        for name, key, higher in METRICS[task]:
            by: dict[str, dict] = defaultdict(dict)
            for e in episodes(path):
                if e.get("episode") is None:
                    continue
                row = e.get("category") or e.get("object")
                by[e["policy"]][(row, e["index"])] = float(e["episode"]["metrics"][key])
            for p in (a.base, a.variant):
                if p not in by:
                    sys.exit(f"error: {path} has no episodes of `{p}`")
            shared = by[a.base].keys() & by[a.variant].keys()
            diff = {s: by[a.variant][s] - by[a.base][s] for s in shared}
            (mb, hb), (mv, hv), (d, hd) = stratified(by[a.base]), stratified(by[a.variant]), stratified(diff)
            better = (d - hd > 0) if higher else (d + hd < 0)
            print(
                f"| {run.name} | {name} | {mb:.2f} ± {hb:.2f} | {mv:.2f} ± {hv:.2f} | "
                f"{d:+.2f} ± {hd:.2f} | {'yes' if better else 'no'} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
