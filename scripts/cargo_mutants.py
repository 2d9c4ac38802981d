"""cargo-mutants over the core Rust modules, and the check that every mutant it
reports as missed is one that docs/harmless-mutants.txt lists with its reason.

    .venv/bin/python scripts/cargo_mutants.py               # run every group, then check
    .venv/bin/python scripts/cargo_mutants.py --group action  # one group (sim, action, solver, eval, policy)
    .venv/bin/python scripts/cargo_mutants.py --check       # only check the last runs' reports

Each group mutates one crate's modules and runs the tests that exercise them.
The mutated crate is built at opt-level 0, incrementally, with its
dependencies optimised as in release: a mutant then takes seconds, not the
minute a release build of the crate takes on 2 cores.

A missed mutant is matched to the list by file, function and change, not by
line, so that edits elsewhere in a file do not invalidate the list; a listed
change covers as many survivors as it is listed times. Exit status 1 when a
survivor is not listed (a test is missing, or the list must say why the
mutant cannot matter), or when a listed one is now caught (the list is stale).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HARMLESS = ROOT / "docs" / "harmless-mutants.txt"

# (report folder, crate, modules, extra arguments)
GROUPS = [
    ("out/mutants-sim", "umpnet-sim", ["crates/sim/src/labels.rs"], []),
    *(
        (
            f"out/mutants-{name}",
            "umpnet-sim",
            [f"crates/sim/src/physics/{file}"],
            # The tests that drive the action; the renderer's and the loader's
            # take minutes at opt-level 0 and never reach it. A mutant that
            # stops a drive from ending is a timeout (caught), not a 10-minute wait.
            [
                *(f"--cargo-test-arg={a}" for a in ["--lib", "--test=reference_physics", "--test=pybullet_golden"]),
                *(f"--cargo-test-arg={a}" for a in ["--test=probe", "--test=physics"]),
                "--timeout=240",
            ],
        )
        # The action, and the Gauss-Seidel solver it calls at every step.
        for name, file in [("action", "reference.rs"), ("solver", "pgs.rs")]
    ),
    (
        "out/mutants-eval",
        "umpnet-eval",
        ["crates/eval/src/protocol.rs", "crates/eval/src/episode.rs"],
        # The observation tests check the policy crate's code, not these.
        [
            *(f"--cargo-test-arg={a}" for a in ["--lib", "--test=metrics", "--test=protocol", "--test=benchmark"]),
            "--timeout=240",
        ],
    ),
    (
        "out/mutants-policy",
        "umpnet-policy",
        ["crates/policy/src/cem.rs", "crates/policy/src/policy.rs", "crates/policy/src/observation.rs"],
        ["--test-package", "umpnet-policy", "--test-package", "umpnet-eval"],
    ),
]

# "crates/x.rs:117:43: replace < with <= in second_round" -> without the position
MISSED = re.compile(r"^(?P<file>[^:]+):\d+:\d+: (?P<what>.+)$")


def key(line: str) -> str | None:
    m = MISSED.match(line.strip())
    return f"{m['file']}: {m['what']}" if m else None


def listed() -> Counter:
    out: Counter = Counter()
    for line in HARMLESS.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            mutant, _, reason = line.partition(" -- ")
            if not reason.strip():
                sys.exit(f"{HARMLESS}: `{line}` gives no reason after ' -- '")
            out[mutant.strip()] += 1
    return out


def run(folder: str, crate: str, files: list[str], extra: list[str], iterate: bool = False) -> None:
    env = dict(os.environ, CARGO_PROFILE_RELEASE_INCREMENTAL="true")
    (ROOT / folder).parent.mkdir(parents=True, exist_ok=True)
    cmd = ["cargo", "mutants", "--in-place", "--profile", "release", "-o", folder]
    if iterate:
        # Only the mutants that the last runs did not catch.
        cmd.append("--iterate")
    cmd += ["-C", "--config", "-C", f"profile.release.package.{crate}.opt-level=0", *extra]
    for f in files:
        cmd += ["-f", f]
    print("+", " ".join(cmd), flush=True)
    # Exit status 2 means "some mutants missed" (the check below judges them),
    # 3 "some timed out" (a mutant that never ends its drive is caught).
    status = subprocess.run(cmd, check=False, cwd=ROOT, env=env).returncode
    if status not in (0, 2, 3):
        sys.exit(f"cargo mutants failed with status {status} on {crate}")


def check() -> int:
    missed: Counter = Counter()
    for folder, *_ in GROUPS:
        report = ROOT / folder / "mutants.out" / "missed.txt"
        if not report.is_file():
            sys.exit(f"{report}: no report; run scripts/cargo_mutants.py first")
        missed.update(k for k in map(key, report.read_text().splitlines()) if k)
    allowed = listed()
    unexplained = missed - allowed
    stale = allowed - missed
    for k in sorted(unexplained.elements()):
        print(f"missed and not explained: {k}")
    for k in sorted(stale.elements()):
        print(f"listed as harmless but no longer missed (remove it from {HARMLESS.name}): {k}")
    total = sum(missed.values())
    print(f"{total} missed mutants, {total - sum(unexplained.values())} of them listed as harmless")
    return 1 if unexplained or stale else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check the reports of the last runs")
    names = [folder.removeprefix("out/mutants-") for folder, *_ in GROUPS]
    parser.add_argument("--group", choices=names, action="append", help="run only this group (repeatable)")
    parser.add_argument("--iterate", action="store_true", help="retest only what the last runs did not catch")
    args = parser.parse_args()
    if not args.check:
        for name, group in zip(names, GROUPS, strict=True):
            if args.group is None or name in args.group:
                run(*group, iterate=args.iterate)
    return check()


if __name__ == "__main__":
    sys.exit(main())
