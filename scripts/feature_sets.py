"""Checks that `cargo test`, `cargo build` and the Python extension's build
resolve every shared dependency with the same features, so that each is
compiled once (crates/workspace-hack says why). Run by `make lint`.

    .venv/bin/python scripts/feature_sets.py

Exit status 1 names each crate whose features differ and the features to add
to crates/workspace-hack/Cargo.toml.
"""

from __future__ import annotations

import subprocess
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# `make test-rerun`'s graph; scripts/rerun_profile.py sets it against the others.
RERUN = ["-p", "umpnet-cli", "-e", "normal,build,dev", "-F", "umpnet-cli/rerun"]
# (what builds it, cargo tree arguments)
GRAPHS = {
    "cargo test (default members)": ["-e", "normal,build,dev"],
    "cargo build (the umpnet binary)": ["-p", "umpnet-cli", "-e", "normal,build"],
    "maturin (the Python extension)": ["-p", "umpnet-py", "-e", "normal,build", "-F", "pyo3/extension-module"],
    "make test-rerun (the CLI with Rerun)": RERUN,
    # `make mutants-ci` tests umpnet-eval alone (scripts/mutants.py). Its
    # tests of umpnet-policy's lib build that crate's own graph (criterion's
    # clap, no rapier), which only an umpnet-policy dependency on the hack
    # could unify; that baseline costs about a minute.
    "make mutants-ci (umpnet-eval's tests)": ["-p", "umpnet-eval", "-e", "normal,build,dev"],
}


def features(args: list[str]) -> dict[str, set[str]]:
    cmd = ["cargo", "tree", "--prefix", "none", "-f", "{p}|{f}", *args]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=True).stdout
    found: dict[str, set[str]] = defaultdict(set)
    for line in out.splitlines():
        package, _, feats = line.removesuffix(" (*)").partition("|")
        # "syn v2.0.1 (proc-macro)" and "umpnet-sim v0.1.0 (/path)": name and version
        name = " ".join(package.split()[:2])
        found[name].update(f for f in feats.split(",") if f)
    return found


def main() -> int:
    graphs = {label: features(args) for label, args in GRAPHS.items()}
    union: dict[str, set[str]] = defaultdict(set)
    for found in graphs.values():
        for name, feats in found.items():
            union[name] |= feats
    bad = 0
    for label, found in graphs.items():
        for name, feats in sorted(found.items()):
            # The CLI itself: its `rerun` feature is what tells the last graph apart.
            if feats != union[name] and not name.startswith("umpnet-cli "):
                bad += 1
                print(f"{name}: {label} builds it without {sorted(union[name] - feats)}")
    if bad:
        print("add these features to crates/workspace-hack/Cargo.toml", file=sys.stderr)
        return 1
    print(f"feature sets agree across {len(GRAPHS)} build graphs ({len(union)} crates)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
