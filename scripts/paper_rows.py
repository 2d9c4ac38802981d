"""The paper's per-category tables beside an evaluation's.

    .venv/bin/python scripts/paper_rows.py out/explore [out/goal] [--json]

Reads each DIR/results.json (`umpnet eval --out DIR`, either task, any
split) and prints, per metric and category, each policy's mean with the
half-width of its 95% interval, next to the paper's figure for the method it
stands for (umpnet: UMPNet; where2act, aot-only, signed-dist, single-step,
inverse: the paper's baselines of those names; a run with
`--direction-filter prev90`: the +HP rows). Averages are over the categories
of a split, as the paper's. The paper's numbers are in
scripts/data/paper_tables.json, with their source.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

PAPER = Path(__file__).resolve().parent / "data" / "paper_tables.json"
# A policy name of this project -> the paper's method.
METHODS = {
    "umpnet": "UMPNet",
    "where2act": "Where2Act",
    "aot-only": "AoTOnly",
    "signed-dist": "SignedDist",
    "single-step": "SingleStep",
    "inverse": "Inverse",
}
TITLES = {
    "novel_state_ratio": "novel-state ratio (higher is better)",
    "single_action_effect": "single action effect (higher is better)",
    "success_rate": "goal success (higher is better)",
    "normalized_distance": "goal normalised distance (lower is better)",
}


def paper_method(policy: str, direction_filter: str | None) -> str | None:
    method = METHODS.get(policy)
    if method and direction_filter == "prev90":
        return f"{method}+HP"
    return method


def load(run: Path) -> dict:
    path = run / "results.json"
    if not path.is_file():
        sys.exit(f"error: {path} not found: run `umpnet eval --out {run}` first")
    try:
        return json.loads(path.read_text())["summary"]
    except (json.JSONDecodeError, KeyError) as e:
        sys.exit(f"error: {path}: not the results of `umpnet eval` ({e})")


def rows(summary: dict, paper: dict) -> list[dict]:
    """One row per (metric, category, policy) with the run's and the paper's value."""
    categories = paper["categories"]
    order = summary.get("policies", [])
    # The filter applies to learned policies only (those with a package).
    hp = summary.get("direction_filter") == "prev90"
    learned = summary.get("models", {})
    out = []
    for cell in summary["cells"]:
        metric, category = cell["metric"], cell.get("category")
        if metric not in paper["metrics"] or category not in categories:
            continue
        filtered = hp and cell["policy"] in learned
        method = paper_method(cell["policy"], "prev90" if filtered else None)
        theirs = paper["metrics"][metric].get(method) if method else None
        k = categories.index(category)
        out.append(
            {
                "metric": metric,
                "category": category,
                "split": "train" if k < 12 else "test",
                "policy": cell["policy"] + ("+prev90" if filtered else ""),
                "mean": cell["mean"],
                "ci95": cell["ci95"],
                "n": cell["n"],
                "order": order.index(cell["policy"]) if cell["policy"] in order else len(order),
                "paper_method": method if theirs else None,
                "paper": theirs[k] if theirs else None,
            }
        )
    return out


def markdown(table: list[dict], categories: list[str]) -> str:
    lines = []
    for metric, title in TITLES.items():
        mine = [r for r in table if r["metric"] == metric]
        if not mine:
            continue
        # The runs in the order given, each run's policies in its order.
        policies = list(dict.fromkeys(r["policy"] for r in sorted(mine, key=lambda r: (r["run"], r["order"]))))
        # Each policy's column, then the paper's method it stands for.
        columns = []
        for p in policies:
            columns.append((p, "mine"))
            method = next((r["paper_method"] for r in mine if r["policy"] == p and r["paper_method"]), None)
            if method:
                columns.append((p, method))
        head = [("paper: " + c if c != "mine" else p) for p, c in columns]
        lines += [f"### {title}", "", "| category | " + " | ".join(head) + " |", "|---" * (len(head) + 1) + "|"]
        # A policy in several runs (the oracle every eval adds) shows the first run's.
        cell: dict[tuple[str, str], dict] = {}
        for r in sorted(mine, key=lambda r: r["run"]):
            cell.setdefault((r["policy"], r["category"]), r)
        for split in ("train", "test"):
            of_split = categories[:12] if split == "train" else categories[12:]
            cats = [c for c in of_split if any((p, c) in cell for p in policies)]
            sums: dict[tuple[str, str], list[float]] = {}
            for c in cats:
                out = []
                for p, col in columns:
                    r = cell.get((p, c))
                    v = None if r is None else (r["mean"] if col == "mine" else r["paper"])
                    if v is not None:
                        sums.setdefault((p, col), []).append(v)
                    if r is None:
                        out.append("-")
                    elif col == "mine":
                        out.append(f"{r['mean']:.2f} ± {r['ci95']:.2f}")
                    else:
                        out.append(f"{r['paper']:.2f}")
                lines.append(f"| {c} | " + " | ".join(out) + " |")
            if cats:
                avg = [
                    f"**{sum(sums[k]) / len(sums[k]):.2f}**" if sums.get(k) else "-"
                    for k in ((p, col) for p, col in columns)
                ]
                label = "training categories (novel instances)" if split == "train" else "test categories"
                lines.append(f"| **average, {label}** | " + " | ".join(avg) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="folders of `umpnet eval --out`")
    parser.add_argument("--json", action="store_true", help="one JSON list of rows instead of Markdown")
    args = parser.parse_args(argv)
    paper = json.loads(PAPER.read_text())
    table = [dict(r, run=k) for k, run in enumerate(args.runs) for r in rows(load(run), paper)]
    if args.json:
        print(json.dumps(table))
    else:
        print(f"Paper: {paper['source']}.\n")
        print(markdown(table, paper["categories"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
