"""Writes the cargo config `make test-rerun` builds with: every crate that only
the CLI's `rerun` feature brings in (the Rerun SDK's ~300) at opt-level 0.

    .venv/bin/python scripts/rerun_profile.py target/rerun-profile.toml
    cargo test --release -p umpnet-cli --features umpnet-cli/rerun --config target/rerun-profile.toml

Why: the test only checks that recordings are written and read back, yet
optimising the SDK (arrow, re_types, the gRPC stack) was most of CI's
Rerun step. The crates the other builds share keep the release profile, so
nothing already built is built again. Users' `--features rerun` builds are
untouched: this file is only passed by that make target.

Crates are named with their version (`name@version`), so a crate the Rerun
SDK uses at another version than the rest of the workspace changes only
its own copy.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# The release builds of `make test` other than the Rerun one (scripts/feature_sets.py).
SHARED = [
    ["-e", "normal,build,dev"],
    ["-p", "umpnet-cli", "-e", "normal,build"],
    ["-p", "umpnet-py", "-e", "normal,build", "-F", "pyo3/extension-module"],
]
RERUN = ["-p", "umpnet-cli", "-e", "normal,build,dev", "-F", "umpnet-cli/rerun"]


def packages(args: list[str]) -> set[tuple[str, str]]:
    """(name, version) of every registry crate in one build graph."""
    cmd = ["cargo", "tree", "--prefix", "none", "-f", "{p}", *args]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=True).stdout
    found = set()
    for line in filter(None, out.splitlines()):  # a blank line between the workspace's roots
        # "syn v2.0.1 (proc-macro)", "umpnet-sim v0.1.0 (/path)", "rand v0.9.1 (*)"
        name, version, *rest = line.split()
        if not any(r.startswith("(/") for r in rest):
            found.add((name, version.removeprefix("v")))
    return found


def config(only_rerun: set[tuple[str, str]]) -> str:
    lines = ["# Written by scripts/rerun_profile.py for `make test-rerun`; not for users' builds.\n"]
    for name, version in sorted(only_rerun):
        lines.append(f'[profile.release.package."{name}@{version}"]\nopt-level = 0\n')
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: rerun_profile.py OUT.toml", file=sys.stderr)
        return 2
    shared = set().union(*(packages(args) for args in SHARED))
    only_rerun = packages(RERUN) - shared
    out = Path(argv[0])
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(config(only_rerun))
    print(f"{out}: {len(only_rerun)} crates only the Rerun build needs, at opt-level 0")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
