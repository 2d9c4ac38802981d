"""Writes the cargo config `make test-rerun` builds with: every crate that only
the CLI's `rerun` feature brings in (the Rerun SDK's ~300) at opt-level 0.

    .venv/bin/python scripts/rerun_profile.py target/rerun-profile.toml
    cargo clippy --release -p umpnet-cli --features umpnet-cli/rerun --all-targets --config target/rerun-profile.toml
    cargo test --release -p umpnet-cli --features umpnet-cli/rerun --config target/rerun-profile.toml

Why: the test only checks that recordings are written and read back, yet
optimising the SDK (arrow, re_types, the gRPC stack) was most of CI's
Rerun step. The crates the other builds share keep the release profile, so
nothing already built is built again. Users' `--features rerun` builds are
untouched: this file is only passed by that target and `make lint-rerun`,
whose clippy reads it so that the SDK's build scripts, which are handed
the profile, run once for both.

Crates are named with their version (`name@version`), so a crate the Rerun
SDK uses at another version than the rest of the workspace changes only
its own copy.
"""

from __future__ import annotations

import sys
from pathlib import Path

from feature_sets import GRAPHS, RERUN, features


def config(only_rerun: set[str]) -> str:
    lines = ["# Written by scripts/rerun_profile.py for `make test-rerun`; not for users' builds.\n"]
    for name, version in sorted(p.split(" v", 1) for p in only_rerun):
        lines.append(f'[profile.release.package."{name}@{version}"]\nopt-level = 0\n')
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: rerun_profile.py OUT.toml", file=sys.stderr)
        return 2
    # The workspace's own crates are in every graph, so only registry crates remain.
    shared = set().union(*(features(args) for args in GRAPHS.values() if args is not RERUN))
    # feature_sets' keys: "name vVERSION"
    only_rerun = set(features(RERUN)) - shared
    out = Path(argv[0])
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(config(only_rerun))
    print(f"{out}: {len(only_rerun)} crates only the Rerun build needs, at opt-level 0")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
