"""The Ray driver (`python -m umpnet.ray eval`) on a local cluster: its merged
report equals the single-process run, and failed shards are retried, then
reported by name."""

import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UMPNET = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
EVAL = ["--task", "goal", "--categories", "Door,Laptop,Box", "--episodes-per-category", "3"]
EVAL += ["--policies", "random,umpnet", "--renderer", "cpu"]


def driver(*args, umpnet_bin=UMPNET):
    cmd = [sys.executable, "-m", "umpnet.ray", "eval", "--num-cpus", "2", "--umpnet-bin", umpnet_bin, *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)


def without_wall_time(path: Path) -> bytes:
    return re.sub(rb'"wall_seconds":[-0-9.eE+]+', b"", path.read_bytes())


def test_ray_eval_on_a_local_cluster_equals_the_single_run(tmp_path):
    whole = tmp_path / "whole"
    subprocess.run([UMPNET, "eval", *EVAL, "--out", str(whole)], check=True, capture_output=True, timeout=600)
    p = driver("--shards", "3", *EVAL, "--out", str(tmp_path / "ray"))
    assert p.returncode == 0, p.stderr
    assert len(re.findall(r"shard \d/3 done", p.stderr)) == 3  # progress, one line per shard
    merged = tmp_path / "ray"
    assert without_wall_time(merged / "results.json") == without_wall_time(whole / "results.json")
    for name in ("episodes.jsonl", "results.csv", "results.md", "results.tex", "table.txt", "curve.png", "curve.svg"):
        assert (merged / name).read_bytes() == (whole / name).read_bytes(), name
    assert len(list((merged / "shards").iterdir())) == 3
    summary = json.loads((merged / "results.json").read_text())["summary"]
    assert "shard" not in summary and summary["failed_episodes"] == 0


def test_a_failing_shard_is_retried_then_reported_by_name(tmp_path):
    # A stand-in for a flaky machine: shard 1/3 fails on its first try only,
    # shard 2/3 always fails; everything else is the real binary.
    marks = tmp_path / "marks"
    marks.mkdir()
    flaky = tmp_path / "flaky-umpnet"
    flaky.write_text(
        "#!/usr/bin/env bash\n"
        'shard=""; prev=""; for a in "$@"; do [ "$prev" = "--shard" ] && shard="$a"; prev="$a"; done\n'
        f'if [ "$shard" = "1/3" ] && [ ! -e {marks}/once ]; then touch {marks}/once; echo "error: lost node" >&2; exit 1; fi\n'
        'if [ "$shard" = "2/3" ]; then echo "error: disk full" >&2; exit 1; fi\n'
        f'exec {UMPNET} "$@"\n'
    )
    flaky.chmod(0o755)
    p = driver("--shards", "3", "--retries", "1", *EVAL, "--out", str(tmp_path / "ray"), umpnet_bin=str(flaky))
    assert p.returncode == 1
    assert "shard 2/3 failed after 2 attempts" in p.stderr and "disk full" in p.stderr
    assert "shard 1/3 done" in p.stderr and "shard 3/3 done" in p.stderr  # 1/3 recovered on its retry
    assert (marks / "once").exists()
    assert not (tmp_path / "ray" / "results.json").exists()  # no partial report
    # The shards that finished are kept, whole.
    kept = sorted(d.name for d in (tmp_path / "ray" / "shards").iterdir())
    assert kept == ["0001-of-0003", "0003-of-0003"], kept
    assert (tmp_path / "ray" / "shards" / kept[0] / "episodes.jsonl").stat().st_size > 0


def test_bad_arguments_fail_before_the_cluster_starts():
    p = driver("--shards", "2", "--task", "bogus")
    assert p.returncode == 2 and "bogus" in p.stderr
    p = driver("--shard", "1/2")
    assert p.returncode == 2 and "set by the driver" in p.stderr
