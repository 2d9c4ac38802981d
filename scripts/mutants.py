"""Hand-made mutants: plausible one-line bugs in the code that decides what
users and training see, each run against the tests that must catch it.

    .venv/bin/python scripts/mutants.py          # all of them
    .venv/bin/python scripts/mutants.py --ci     # the fixed subset `make test` runs
    .venv/bin/python scripts/mutants.py --json

The CI subset is the five deliberate bugs of the test audit (issue 18): the
novel-state threshold, the AoT class map, exploration ignoring AoT, RGB read
as BGR, the goal reward's sign. The rest cover the gymnasium rewards and ends
and the training losses and collection (no Python mutation tool runs
cleanly against a pyo3 extension here, hence a list). `make mutants` adds
cargo-mutants over the core Rust modules (docs/testing.md).

Each mutant is applied to the source in place, its tests run, and the source
is restored (also on Ctrl-C). Exit status 1 if any mutant survives.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GYM = "crates/py/python/umpnet/gym.py"
TRAIN = "train_py/umpnet_train/train.py"
COLLECT = "train_py/umpnet_train/collect.py"
PYTEST = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:warnings"]
GYM_TESTS = [*PYTEST, "crates/py/tests/test_bindings.py", "crates/py/tests/test_gym_vector.py", "-k", "gym"]
TRAINING = [*PYTEST, "train_py/tests/test_runtime_semantics.py", "train_py/tests/test_train.py"]
CARGO = ["cargo", "test", "--release", "-q"]

# (name, file, original text, mutated text, test command, in the CI subset)
MUTANTS = [
    ("novel-state threshold δ -> δ/3", "crates/eval/src/protocol.rs",
     "if v - last > DELTA {", "if v - last > DELTA / 3.0 {",
     [*CARGO, "-p", "umpnet-eval", "--lib", "--test", "metrics"], True),
    ("AoT class map cls-1 -> 1-cls", "crates/policy/src/policy.rs",
     "    cls as i8 - 1\n", "    1 - cls as i8\n", [*CARGO, "-p", "umpnet-policy", "--lib"], True),
    ("exploration picks max distance, ignoring AoT", "crates/policy/src/cem.rs",
     "Mode::Explore => best(&|s| s.aot == wanted).or_else(|| best(&|_| true)),",
     "Mode::Explore => best(&|_| true),", [*CARGO, "-p", "umpnet-policy", "--lib"], True),
    ("RGB read as BGR", "crates/policy/src/observation.rs",
     "o[3] = rgb[0] as f32", "o[3] = rgb[2] as f32", [*CARGO, "-p", "umpnet-eval", "--test", "observation"], True),
    ("goal reward sign", GYM,
     "reward = (np.abs(before - goal) - np.abs(after - goal)) / DELTA",
     "reward = (np.abs(after - goal) - np.abs(before - goal)) / DELTA", GYM_TESTS, True),
    ("exploration pays going back", GYM,
     "reward = np.maximum(0.0, distance - farthest) / DELTA",
     "reward = np.maximum(0.0, farthest - distance) / DELTA", GYM_TESTS, False),
    ("goal never succeeds", GYM,
     "return reward, reached, farthest",
     "return reward, reached & False, farthest", GYM_TESTS, False),
    ("exploration ends only at the budget", GYM,
     "return reward, at_limit, np.maximum(farthest, distance)",
     "return reward, at_limit & False, np.maximum(farthest, distance)", GYM_TESTS, False),
    ("AoT class index reversed in the loss", TRAIN,
     "aot_t = to_long(aot + 1)",
     "aot_t = to_long(1 - aot)", TRAINING, False),
    ("distance loss dropped", TRAIN,
     "total = total + cfg.dist_loss_weight * out[f\"loss/{prefix}dist\"]",
     "total = total + 0.0 * out[f\"loss/{prefix}dist\"]", TRAINING, False),
    ("dense classes weighted by count, not balanced", TRAIN,
     "return (1.0 / counts.clamp(min=1))[groups] / present",
     "return counts[groups] / counts.sum()", TRAINING, False),
    ("exploration picks backward candidates", COLLECT,
     "k = {1: 2, -1: 0, 0: None}[w]",
     "k = {1: 0, -1: 2, 0: None}[w]", TRAINING, False),
    ("contradictory policy never turns back", COLLECT,
     "return np.where(turn, -1, heading)",
     "return np.where(turn, 1, heading)", TRAINING, False),
    ("no random warm-up", COLLECT,
     "    if epoch < start_epoch:\n        return 1.0",
     "    if epoch < start_epoch:\n        return 0.0", TRAINING, False),
]  # fmt: skip


def mutated_crate_at_opt_level_0(cmd: list[str], rel: str) -> list[str]:
    """A Rust mutant's crate is rebuilt at opt-level 0 (its dependencies stay
    optimised): seconds per mutant, not the minutes a release build of the
    crate takes on 2 cores. Not incremental, unlike scripts/cargo_mutants.py:
    that setting is the whole profile's, so it would rebuild every workspace
    crate once (about 3 minutes of `make test`) to save little on 5 mutants."""
    if cmd[:2] != ["cargo", "test"] or not rel.startswith("crates/"):
        return cmd
    crate = "umpnet-" + rel.split("/")[1]
    return [*cmd, "--config", f"profile.release.package.{crate}.opt-level=0"]


def run_tests(cmd: list[str], timeout: int) -> tuple[bool, float]:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "train_py")}
    env.setdefault("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout, check=False)
        if "could not compile" in p.stderr or "SyntaxError" in p.stdout + p.stderr:
            raise RuntimeError(f"the mutant does not build, so it proves nothing: {cmd}")
        passed = p.returncode == 0
    except subprocess.TimeoutExpired:
        passed = False  # a hang counts as caught, as cargo-mutants counts timeouts
    return passed, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--ci", action="store_true", help="only the fixed subset that `make test` runs")
    ap.add_argument("-k", dest="match", default="", help="only the mutants whose name contains this text")
    ap.add_argument("--timeout", type=int, default=900, help="seconds per mutant's test run")
    args = ap.parse_args(argv)
    results = []
    for name, rel, old, new, cmd, in_ci in MUTANTS:
        if (args.ci and not in_ci) or args.match not in name:
            continue
        path = ROOT / rel
        original = path.read_text()
        if original.count(old) != 1:
            print(f"error: mutant `{name}`: the original text occurs {original.count(old)} times in {rel}")
            return 2
        try:
            path.write_text(original.replace(old, new))
            passed, secs = run_tests(mutated_crate_at_opt_level_0(cmd, rel), args.timeout)
        finally:
            path.write_text(original)
        results.append({"mutant": name, "file": rel, "caught": not passed, "seconds": round(secs, 1)})
        if not args.json:
            print(f"{'caught ' if not passed else 'MISSED '} {name} ({rel}, {secs:.0f} s)", flush=True)
    missed = [r for r in results if not r["caught"]]
    if args.json:
        print(json.dumps({"mutants": results, "caught": len(results) - len(missed), "missed": len(missed)}))
    else:
        print(f"{len(results) - len(missed)} of {len(results)} mutants caught")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
