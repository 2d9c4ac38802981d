"""cargo-mutants over the core Rust modules, and the check that every mutant it
reports as missed is one that docs/harmless-mutants.txt lists with its reason.

    .venv/bin/python scripts/cargo_mutants.py                 # run every group, then check
    .venv/bin/python scripts/cargo_mutants.py --group action  # one group (sim, action, solver, ideal, eval, policy)
    .venv/bin/python scripts/cargo_mutants.py --check --group sim  # only check the committed record

Each group mutates one crate's modules and runs the tests that exercise them.
The mutated crate is built at opt-level 0, incrementally, with its
dependencies optimised as in release: a mutant then takes seconds, not the
minute a release build of the crate takes on 2 cores.

A full run writes docs/mutants/GROUP.txt: the counts, the missed mutants, and
the SHA-256 of the mutated modules and of the group's test sources. The
record is committed; `--check` (which `make test` runs on the groups whose
record is complete) needs no cargo-mutants and takes a second, so CI knows
that the record is of the current sources without spending the run's minutes.

A missed mutant is matched to the list by file, function and change, not by
line, so that edits elsewhere in a file do not invalidate the list; a listed
change covers as many survivors as it is listed times. Exit status 1 when a
survivor is not listed (a test is missing, or the list must say why the
mutant cannot matter), when a listed one is now caught (the list is stale),
or when a record is missing or of other sources (rerun the group).
"""

from __future__ import annotations

import argparse
import datetime
import hashlib
import os
import re
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HARMLESS = ROOT / "docs" / "harmless-mutants.txt"
RECORDS = ROOT / "docs" / "mutants"


@dataclass(frozen=True)
class Group:
    name: str
    crate: str
    # The files cargo-mutants mutates.
    modules: list[str]
    # Test sources outside the modules whose edit can change what is caught:
    # the record goes stale when they change, as when a module does.
    tests: list[str]
    extra: list[str] = field(default_factory=list)

    @property
    def folder(self) -> Path:
        return ROOT / "out" / f"mutants-{self.name}"

    @property
    def record(self) -> Path:
        return RECORDS / f"{self.name}.txt"


# The tests that drive the action; the renderer's and the loader's take
# minutes at opt-level 0 and never reach it. A mutant that stops a drive from
# ending is a timeout (caught), not a 10-minute wait.
ACTION_TESTS = ["reference_physics", "pybullet_golden", "probe", "physics"]
ACTION_ARGS = [*(f"--cargo-test-arg={a}" for a in ["--lib", *(f"--test={t}" for t in ACTION_TESTS)]), "--timeout=240"]
ACTION_SOURCES = [
    *(f"crates/sim/tests/{t}.rs" for t in ACTION_TESTS),
    "crates/sim/tests/data/pybullet_actions.json",
]
EVAL_TESTS = ["metrics", "protocol", "benchmark"]

GROUPS = [
    # labels.rs is tested by its own unit tests.
    Group("sim", "umpnet-sim", ["crates/sim/src/labels.rs"], [], ["--cargo-test-arg=--lib", "--cargo-test-arg=labels"]),
    # The action, the Gauss-Seidel solver it calls at every step, and the
    # ideal profile (rapier3d).
    Group("action", "umpnet-sim", ["crates/sim/src/physics/reference.rs"], ACTION_SOURCES, ACTION_ARGS),
    Group("solver", "umpnet-sim", ["crates/sim/src/physics/pgs.rs"], ACTION_SOURCES, ACTION_ARGS),
    Group("ideal", "umpnet-sim", ["crates/sim/src/physics/ideal.rs"], ACTION_SOURCES, ACTION_ARGS),
    Group(
        "eval",
        "umpnet-eval",
        ["crates/eval/src/protocol.rs", "crates/eval/src/episode.rs"],
        [f"crates/eval/tests/{t}.rs" for t in EVAL_TESTS],
        # The observation tests check the policy crate's code, not these.
        [*(f"--cargo-test-arg={a}" for a in ["--lib", *(f"--test={t}" for t in EVAL_TESTS)]), "--timeout=240"],
    ),
    Group(
        "policy",
        "umpnet-policy",
        [
            "crates/policy/src/cem.rs",
            "crates/policy/src/policy.rs",
            "crates/policy/src/filters.rs",
            "crates/policy/src/observation.rs",
        ],
        sorted(
            str(p.relative_to(ROOT))
            for d in ["crates/policy/tests", "crates/eval/tests"]
            for p in (ROOT / d).rglob("*.rs")
        ),
        ["--test-package", "umpnet-policy", "--test-package", "umpnet-eval"],
    ),
]

# "crates/x.rs:117:43: replace < with <= in second_round" -> without the position
MISSED = re.compile(r"^(?P<file>[^:]+):\d+:\d+: (?P<what>.+)$")
OUTCOMES = ["caught", "missed", "timeout", "unviable"]


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


def digests(group: Group) -> dict[str, str]:
    return {f: hashlib.sha256((ROOT / f).read_bytes()).hexdigest() for f in [*group.modules, *group.tests]}


def run(group: Group, iterate: bool = False) -> None:
    env = dict(os.environ, CARGO_PROFILE_RELEASE_INCREMENTAL="true")
    group.folder.parent.mkdir(parents=True, exist_ok=True)
    before = digests(group)
    cmd = ["cargo", "mutants", "--in-place", "--profile", "release", "-o", str(group.folder.relative_to(ROOT))]
    if iterate:
        # Only the mutants that the last runs did not catch.
        cmd.append("--iterate")
    cmd += ["-C", "--config", "-C", f"profile.release.package.{group.crate}.opt-level=0", *group.extra]
    for f in group.modules:
        cmd += ["-f", f]
    print("+", " ".join(cmd), flush=True)
    # Exit status 2 means "some mutants missed" (the check below judges them),
    # 3 "some timed out" (a mutant that never ends its drive is caught).
    status = subprocess.run(cmd, check=False, cwd=ROOT, env=env).returncode
    if status not in (0, 2, 3):
        sys.exit(f"cargo mutants failed with status {status} on {group.crate}")
    if iterate:
        print(f"{group.record.relative_to(ROOT)} not updated: --iterate retests only part of the group")
    elif digests(group) != before:
        print(f"{group.record.relative_to(ROOT)} not updated: the sources changed during the run")
    else:
        write_record(group, before)


def write_record(group: Group, sources: dict[str, str]) -> None:
    """What a full run found, with the hashes of the sources it ran on."""
    out = group.folder / "mutants.out"
    found = {o: [k for k in map(key, (out / f"{o}.txt").read_text().splitlines()) if k] for o in OUTCOMES}
    version = subprocess.run(
        ["cargo", "mutants", "--version"], check=True, capture_output=True, text=True
    ).stdout.strip()
    lines = [
        f"# {version} over {group.crate}, {datetime.date.today()}: scripts/cargo_mutants.py --group {group.name}",
        "# " + ", ".join(f"{o} {len(found[o])}" for o in OUTCOMES),
        *(f"sha256 {h} {f}" for f, h in sources.items()),
        *(f"missed {k}" for k in sorted(found["missed"])),
    ]
    RECORDS.mkdir(parents=True, exist_ok=True)
    group.record.write_text("\n".join(lines) + "\n")
    print(f"wrote {group.record.relative_to(ROOT)}")


def read_record(group: Group) -> tuple[dict[str, str], Counter]:
    name = group.record.relative_to(ROOT)
    if not group.record.is_file():
        sys.exit(f"{name}: no record; run `scripts/cargo_mutants.py --group {group.name}`")
    sources: dict[str, str] = {}
    missed: Counter = Counter()
    for n, line in enumerate(group.record.read_text().splitlines(), 1):
        kind, _, rest = line.partition(" ")
        if kind == "sha256":
            digest, _, path = rest.partition(" ")
            sources[path] = digest
        elif kind == "missed":
            missed[rest] += 1
        elif kind != "#":
            sys.exit(f"{name}:{n}: expected `# ...`, `sha256 HASH FILE` or `missed CHANGE`, got {line!r}")
    return sources, missed


def check(groups: list[Group]) -> int:
    """Judges the committed records of `groups`: each must be of the current
    sources, and its missed mutants exactly the list entries for its files."""
    missed: Counter = Counter()
    files = set()
    stale_records = []
    for group in groups:
        sources, found = read_record(group)
        if sources != digests(group):
            changed = sorted(f for f in {*sources, *digests(group)} if sources.get(f) != digests(group).get(f))
            stale_records.append(
                f"{group.record.relative_to(ROOT)} is of other sources ({', '.join(changed)}): "
                f"rerun `scripts/cargo_mutants.py --group {group.name}`"
            )
        missed.update(found)
        files.update(group.modules)
    allowed = Counter({k: n for k, n in listed().items() if k.split(": ", 1)[0] in files})
    unexplained = missed - allowed
    stale = allowed - missed
    for line in stale_records:
        print(line)
    for k in sorted(unexplained.elements()):
        print(f"missed and not explained: {k}")
    for k in sorted(stale.elements()):
        print(f"listed as harmless but no longer missed (remove it from {HARMLESS.name}): {k}")
    total = sum(missed.values())
    names = ", ".join(g.name for g in groups)
    print(f"{names}: {total} missed mutants, {total - sum(unexplained.values())} of them listed as harmless")
    return 1 if unexplained or stale or stale_records else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only check the committed records")
    names = [g.name for g in GROUPS]
    parser.add_argument("--group", choices=names, action="append", help="only this group (repeatable)")
    parser.add_argument("--iterate", action="store_true", help="retest only what the last runs did not catch")
    args = parser.parse_args()
    chosen = [g for g in GROUPS if args.group is None or g.name in args.group]
    if not args.check:
        for group in chosen:
            run(group, iterate=args.iterate)
    return check(chosen)


if __name__ == "__main__":
    sys.exit(main())
