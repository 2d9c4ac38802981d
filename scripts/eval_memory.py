"""What an evaluation costs in memory and disk as it grows: peak RSS of
`umpnet eval` at N and 10N episodes per category, MB of memory and of
episodes.jsonl per 1,000 episodes, and the peak RSS of `umpnet eval merge`
over many shards.

    .venv/bin/python scripts/eval_memory.py [--episodes 20] [--shards 1000] [--json]

Random policy (plus the oracle every evaluation adds), exploration, all 22
categories, CPU renderer. Peak RSS is the process's own, from wait4.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UMPNET = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))


def measure(args: list[str]) -> tuple[float, float]:
    """Peak RSS (MB) and wall seconds of one umpnet command."""
    t0 = time.perf_counter()
    p = subprocess.Popen([UMPNET, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(p.pid, 0)
    err = p.stderr.read().decode() if p.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"error: umpnet {' '.join(args[:3])}...: {err.strip()}")
    return usage.ru_maxrss / 1024, time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--episodes", type=int, default=20, help="N: episodes per category of the small run")
    p.add_argument("--shards", type=int, default=1000, help="shards merged (0: skip the merge)")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    if a.episodes < 1 or a.shards < 0:
        p.error("--episodes must be at least 1 and --shards at least 0")
    common = ["--json", "eval", "--policies", "random", "--renderer", "cpu"]
    report: dict = {"runs": []}
    with tempfile.TemporaryDirectory(prefix="umpnet-memory-") as tmp:
        for n in (a.episodes, 10 * a.episodes):
            out = Path(tmp, f"run{n}")
            rss, wall = measure([*common, "--episodes-per-category", str(n), "--out", str(out)])
            episodes = json.loads((out / "results.json").read_text())["summary"]["episodes"]
            report["runs"].append(
                {
                    "episodes": episodes,
                    "peak_rss_mb": round(rss, 1),
                    "wall_seconds": round(wall, 1),
                    "episodes_jsonl_mb": round((out / "episodes.jsonl").stat().st_size / 2**20, 2),
                    "results_json_kb": round((out / "results.json").stat().st_size / 1024, 1),
                }
            )
        small, large = report["runs"]
        grown = large["episodes"] - small["episodes"]
        report["rss_mb_per_1000_episodes"] = round(1000 * (large["peak_rss_mb"] - small["peak_rss_mb"]) / grown, 3)
        report["disk_mb_per_1000_episodes"] = round(1000 * large["episodes_jsonl_mb"] / large["episodes"], 2)
        if a.shards:
            shards = []
            for k in range(1, a.shards + 1):
                d = Path(tmp, "shards", str(k))
                args = [*common, "--threads", "1", "--episodes-per-category", str(a.episodes)]
                subprocess.run([UMPNET, *args, "--shard", f"{k}/{a.shards}", "--out", str(d)], check=True,
                               capture_output=True)  # fmt: skip
                shards.append(str(d))
            rss, wall = measure(["eval", "merge", *shards, "--out", str(Path(tmp, "merged"))])
            report["merge"] = {"shards": a.shards, "peak_rss_mb": round(rss, 1), "wall_seconds": round(wall, 1)}
    if a.json:
        print(json.dumps(report, indent=2))
        return 0
    print("episodes  peak RSS (MB)  wall (s)  episodes.jsonl (MB)  results.json (KB)")
    for r in report["runs"]:
        print(
            f"{r['episodes']:>8}  {r['peak_rss_mb']:>13}  {r['wall_seconds']:>8}  "
            f"{r['episodes_jsonl_mb']:>19}  {r['results_json_kb']:>17}"
        )
    print(f"memory per 1,000 more episodes: {report['rss_mb_per_1000_episodes']} MB")
    print(f"disk per 1,000 episodes: {report['disk_mb_per_1000_episodes']} MB")
    if "merge" in report:
        m = report["merge"]
        print(f"eval merge of {m['shards']} shards: peak RSS {m['peak_rss_mb']} MB in {m['wall_seconds']} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
