"""Where a policy's episodes go wrong, move by move, per category or object.

    .venv/bin/python scripts/episode_outcomes.py DIR [--policy umpnet] [--json]

DIR is an `umpnet eval --out` folder. For each row (a category, or an
object of `--objects`) and one policy it counts:

- grasps: the share of episodes whose grasp landed on the part;
- of the valid grasps, episodes whose moves never moved the part (`dead`),
  whose first move failed but a later one moved it (`late`), and the rest
  (`moved`), each with the episode score's mean (novel-state ratio exploring,
  success toward a goal);
- of the moves after a valid grasp, the share that moved nothing (`still`),
  that moved the part by δ or less (`small`: Arrow of Time 0), that moved it
  back toward its start (`back`), and that ended at a joint limit (`limit`).

The labels are the simulator's ground truth recorded with each move, so the
breakdown says which decision loses: the grasp, the first move, or the moves
that follow one that worked.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

from baselines_table import episodes

COLUMNS = ["episodes", "grasps", "dead", "late", "moved", "score_dead", "score_late", "score_moved"]
MOVES = ["moves", "still", "small", "back", "limit"]


def score(episode: dict) -> float:
    m = episode["metrics"]
    if episode["scene"]["task"] == "goal":
        return float(m["success"])
    return float(m["novel_state_ratio"])


def outcomes(records, policy: str) -> dict[str, dict[str, float]]:
    """row -> the counts above, for `policy`'s episodes among `records` (the
    lines of an episodes file)."""
    raw: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
    for r in records:
        if r["policy"] != policy or r.get("error") is not None:
            continue
        ep = r["episode"]
        row = raw[r.get("category") or r.get("object") or "?"]
        row["episodes"] += 1
        if not ep["valid_position"]:
            continue
        row["grasps"] += 1
        labels = [s["record"]["labels"] for s in ep["steps"]]
        moved = [lab["moved"] for lab in labels]
        kind = "dead" if not any(moved) else "late" if not moved[0] else "moved"
        row[kind] += 1
        row[f"score_{kind}"] += score(ep)
        for lab in labels:
            row["moves"] += 1
            row["still"] += not lab["moved"]
            row["small"] += lab["moved"] and lab["aot"] == 0
            row["back"] += lab["moved"] and lab["aot"] == -1
            row["limit"] += lab["reached_limit"]
    out = {}
    for name, row in sorted(raw.items()):
        grasps = max(row["grasps"], 1)
        moves = max(row["moves"], 1)
        out[name] = {
            "episodes": int(row["episodes"]),
            "grasps": row["grasps"] / row["episodes"],
            **{k: row[k] / grasps for k in ("dead", "late", "moved")},
            **{f"score_{k}": row[f"score_{k}"] / row[k] if row[k] else None for k in ("dead", "late", "moved")},
            "moves": int(row["moves"]),
            **{k: row[k] / moves for k in MOVES[1:]},
        }
    return out


def table(rows: dict[str, dict[str, float]]) -> str:
    head = ["row", *COLUMNS, *MOVES]
    lines = [" | ".join(head), " | ".join("---" for _ in head)]
    for name, r in rows.items():
        cells = [name]
        for k in COLUMNS + MOVES:
            v = r[k]
            cells.append("-" if v is None else str(v) if isinstance(v, int) else f"{v:.2f}")
        lines.append(" | ".join(cells))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="an eval --out folder")
    ap.add_argument("--policy", default="umpnet", help="the policy to break down (default umpnet)")
    ap.add_argument("--json", action="store_true", help="print the breakdown as JSON")
    a = ap.parse_args(argv)
    results = a.run / "results.json"
    if not results.is_file():
        sys.exit(f"error: {a.run} holds no results.json; expected an `umpnet eval --out` folder")
    rows = outcomes(episodes(results), a.policy)
    if not rows:
        sys.exit(f"error: {a.run} has no episodes of policy `{a.policy}`")
    print(json.dumps(rows, indent=2) if a.json else table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
