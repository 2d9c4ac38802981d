"""The umpnet benchmark on a Ray cluster: `umpnet eval` cut into shards that
run as Ray tasks, then merged into the report of one run.

    python -m umpnet.ray eval --shards 8 --task goal --split test \\
        --policies umpnet,random --out out/goal
    python -m umpnet.ray eval --address ray://head:10001 --shards 200 ...

Every argument it does not know goes to `umpnet eval` unchanged. Each task
runs `umpnet eval ... --shard K/N` with the `umpnet` binary of its machine
(`--umpnet-bin`, else $UMPNET_BIN, else `umpnet` on PATH) and returns the
shard's results.json and episodes.jsonl; the driver writes each shard under
OUT/shards as it arrives and runs `umpnet eval merge`, which streams them. Scenes are pure functions of (seed, task, category,
index), so the merged report equals a single run's, byte for byte except the
wall time. Model packages and object files must be at the same paths on every
machine (see docs/ray.md).

Without --address a local cluster is started (`ray.init()`), with
--num-cpus CPUs. Needs the `ray` extra: `pip install umpnet[ray]`.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path


class ShardFailed(RuntimeError):
    """`umpnet eval --shard K/N` exited with an error."""


def _run_shard(umpnet_bin: str, eval_args: list[str], cwd: str, shard: str) -> dict[str, bytes]:
    """One shard, on whichever machine Ray chose: its results.json and
    episodes file, by name."""
    workdir = cwd if os.path.isdir(cwd) else None
    with tempfile.TemporaryDirectory(prefix="umpnet-shard-") as out:
        cmd = [umpnet_bin, "--json", "eval", *eval_args, "--shard", shard, "--out", out]
        try:
            p = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, check=False)
        except OSError as e:
            raise ShardFailed(f"shard {shard}: cannot run {umpnet_bin}: {e}") from e
        if p.returncode != 0:
            tail = (p.stderr.strip().splitlines() or ["(no message)"])[-1]
            raise ShardFailed(f"shard {shard}: umpnet exited {p.returncode}: {tail}")
        results = Path(out, "results.json").read_bytes()
        name = json.loads(results)["episodes_file"]
        return {"results.json": results, name: Path(out, name).read_bytes()}


def _umpnet_bin(given: str | None) -> str:
    found = given or os.environ.get("UMPNET_BIN") or shutil.which("umpnet")
    if not found:
        raise SystemExit("error: no umpnet binary: pass --umpnet-bin PATH or set UMPNET_BIN")
    return str(Path(found).resolve()) if Path(found).exists() else found


def parse_args(argv: list[str] | None = None) -> tuple[argparse.Namespace, list[str]]:
    p = argparse.ArgumentParser(
        prog="python -m umpnet.ray",
        allow_abbrev=False,  # --shard (for umpnet eval) must not pass for --shards
        description="Run `umpnet eval` as shards on a Ray cluster and merge them. "
        "Arguments not listed here go to `umpnet eval`.",
    )
    p.add_argument("command", choices=["eval"], help="what to run (eval: the benchmark)")
    p.add_argument("--shards", type=int, default=None, help="number of shards (default: the cluster's CPUs)")
    p.add_argument("--address", default=None, help="an existing cluster (as for ray.init); default: a local one")
    p.add_argument("--num-cpus", type=int, default=None, help="CPUs of the local cluster (default: all)")
    p.add_argument("--cpus-per-shard", type=int, default=1, help="CPUs (and umpnet threads) per shard task")
    p.add_argument("--retries", type=int, default=1, help="retries of a failed shard before it is reported")
    p.add_argument("--umpnet-bin", default=None, help="the umpnet binary on every machine")
    p.add_argument("--out", type=Path, default=None, help="the merged report, with the shards in OUT/shards")
    p.add_argument("--force", action="store_true", help="replace the report a previous run left in --out")
    p.add_argument("--json", action="store_true", help="print the merged summary as JSON")
    args, rest = p.parse_known_args(argv)
    for flag in ("--shard", "--threads"):
        if any(a == flag or a.startswith(flag + "=") for a in rest):
            p.error(f"{flag} is set by the driver (see --shards and --cpus-per-shard)")
    if args.shards is not None and args.shards < 1:
        p.error(f"--shards {args.shards}: expected at least 1")
    if args.cpus_per_shard < 1 or args.retries < 0:
        p.error("--cpus-per-shard must be at least 1 and --retries at least 0")
    return args, rest


def main(argv: list[str] | None = None) -> int:
    args, eval_args = parse_args(argv)
    try:
        import ray
    except ImportError:
        print("error: Ray is not installed: pip install 'umpnet[ray]'", file=sys.stderr)
        return 2
    umpnet_bin = _umpnet_bin(args.umpnet_bin)
    # Check the arguments here, once, before any cluster work: a typo would fail every shard.
    check = subprocess.run(
        [umpnet_bin, "eval", *eval_args, "--shard", "1/1", "--help"], capture_output=True, text=True, check=False
    )
    if check.returncode != 0:
        print(check.stderr.strip(), file=sys.stderr)
        return 2
    if args.address:
        ray.init(address=args.address, log_to_driver=False)
    else:
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, log_to_driver=False)
    try:
        n = args.shards or max(int(ray.cluster_resources().get("CPU", 1)) // args.cpus_per_shard, 1)
        task = ray.remote(num_cpus=args.cpus_per_shard, max_retries=args.retries, retry_exceptions=True)(_run_shard)
        forwarded = [*eval_args, "--threads", str(args.cpus_per_shard)]
        pending = {task.remote(umpnet_bin, forwarded, os.getcwd(), f"{k}/{n}"): k for k in range(1, n + 1)}
        out = args.out
        shard_root = (out / "shards") if out else Path(tempfile.mkdtemp(prefix="umpnet-shards-"))
        done: dict[int, Path] = {}
        failed: list[str] = []
        t0 = time.perf_counter()
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            k = pending.pop(ready[0])
            try:
                files = ray.get(ready[0])
                # Written as each arrives, so the driver holds one shard at a time.
                d = shard_root / f"{k:04d}-of-{n:04d}"
                d.mkdir(parents=True, exist_ok=True)
                for name, data in files.items():
                    (d / Path(name).name).write_bytes(data)
                del files
                done[k] = d
                status = "done"
            except ray.exceptions.RayError as e:  # a task that failed all its tries, or a lost worker
                cause = getattr(e, "cause", None) or e
                failed.append(f"shard {k}/{n} failed after {args.retries + 1} attempts: {cause}")
                status = "FAILED"
            if not args.json:
                print(f"shard {k}/{n} {status} ({len(done) + len(failed)}/{n}, {time.perf_counter() - t0:.0f} s)",
                      file=sys.stderr, flush=True)  # fmt: skip
    finally:
        ray.shutdown()
    if failed:
        print("\n".join(f"error: {f}" for f in failed), file=sys.stderr)
        return 1
    dirs = [str(d) for _, d in sorted(done.items())]
    merge = [umpnet_bin, *(["--json"] if args.json else []), "eval", "merge", *dirs]
    if out:
        merge += ["--out", str(out), *(["--force"] if args.force else [])]
    return subprocess.run(merge, check=False).returncode


if __name__ == "__main__":
    sys.exit(main())
