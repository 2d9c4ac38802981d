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
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# The gym's rewards and ends are Rust's (crates/py/python/umpnet/gym.py calls score_step).
REWARDS = "crates/eval/src/rewards.rs"
TRAIN = "train_py/umpnet_train/train.py"
COLLECT = "train_py/umpnet_train/collect.py"
PYTEST = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:warnings"]
# The files that hold the training mutants' tests (the losses' class order, the
# dense weights, collection's arrows of time, the warm-up's schedule); the quick
# files first, since -x ends a mutant's run at its first failure.
TRAINING = [*PYTEST, *(f"train_py/tests/test_{name}.py" for name in ("runtime_semantics", "config", "learner"))]
CARGO = ["cargo", "test", "--release", "-q"]
REWARD_TESTS = [*CARGO, "-p", "umpnet-eval", "--lib", "rewards"]

# (name, file, original text, mutated text, test command, in the CI subset,
#  the tests written to catch it: the mutant counts as caught only if one of
#  them is among the failures)
MUTANTS = [
    ("novel-state threshold δ -> δ/3", "crates/eval/src/protocol.rs",
     "if v - last > DELTA {", "if v - last > DELTA / 3.0 {",
     [*CARGO, "-p", "umpnet-eval", "--lib", "--test", "metrics"], True, ("paper_unique_states_counts_greedily_over_sorted_values",)),
    ("AoT class map cls-1 -> 1-cls", "crates/policy/src/policy.rs",
     "    cls as i8 - 1\n", "    1 - cls as i8\n", [*CARGO, "-p", "umpnet-policy", "--lib"], True, ("aot_probabilities_are_read_in_the_order_minus_one_zero_plus_one",)),
    ("exploration picks max distance, ignoring AoT", "crates/policy/src/cem.rs",
     "Mode::Explore => best(&|s| s.aot == wanted).or_else(|| best(&|_| true)),",
     "Mode::Explore => best(&|_| true),", [*CARGO, "-p", "umpnet-policy", "--lib"], True, ("selection_follows_the_wanted_arrow_of_time_before_distance",)),
    ("RGB read as BGR", "crates/policy/src/observation.rs",
     "o[3] = rgb[0] as f32", "o[3] = rgb[2] as f32", [*CARGO, "-p", "umpnet-eval", "--test", "observation"], True, ("observation_channels_are_the_frames_world_points_colours_and_depth",)),
    ("goal reward sign", REWARDS,
     "reward: ((before - goal).abs() - (after - goal).abs()) / DELTA,",
     "reward: ((after - goal).abs() - (before - goal).abs()) / DELTA,", REWARD_TESTS, True, ("goal_pays_progress_both_ways_and_ends_at_or_across_the_goal",)),
    ("exploration pays going back", REWARDS,
     "reward: (distance - farthest).max(0.0) / DELTA,",
     "reward: (farthest - distance).max(0.0) / DELTA,", REWARD_TESTS, False, ("exploration_pays_new_distance_once_and_ends_at_a_limit",)),
    ("goal never succeeds", REWARDS,
     "success: protocol::reached_goal(before, after, goal, threshold),",
     "success: protocol::reached_goal(before, after, goal, threshold) && false,", REWARD_TESTS, False, ("goal_pays_progress_both_ways_and_ends_at_or_across_the_goal",)),
    ("exploration ends only at the budget", REWARDS,
     "success: protocol::reached_limit(after, start, lower, upper, threshold),",
     "success: protocol::reached_limit(after, start, lower, upper, threshold) && false,", REWARD_TESTS, False, ("exploration_pays_new_distance_once_and_ends_at_a_limit",)),
    ("AoT class index reversed in the loss", TRAIN,
     "aot_t = to_long(aot + 1)",
     "aot_t = to_long(1 - aot)", TRAINING, False, ("test_training_labels_use_the_class_order_the_runtime_reads",)),
    ("distance loss dropped", TRAIN,
     "total = total + cfg.dist_loss_weight * out[f\"loss/{prefix}dist\"]",
     "total = total + 0.0 * out[f\"loss/{prefix}dist\"]", TRAINING, False, ("test_the_distance_loss_reaches_the_distance_head",)),
    ("dense classes weighted by count, not balanced", TRAIN,
     "return (1.0 / counts.clamp(min=1))[groups] / present",
     "return counts[groups] / counts.sum()", TRAINING, False, ("test_dense_batches_weigh_each_aot_class_equally",)),
    ("exploration picks backward candidates", COLLECT,
     "k = {1: 2, -1: 0, 0: None}[w]",
     "k = {1: 0, -1: 2, 0: None}[w]", TRAINING, False, ("test_training_explores_with_the_wanted_arrow_of_time",)),
    ("contradictory policy never turns back", COLLECT,
     "return np.where(turn, -1, heading)",
     "return np.where(turn, 1, heading)", TRAINING, False, ("test_the_contradictory_policy_turns_at_the_boundary_or_half_way_and_stays_back",)),
    ("no random warm-up", COLLECT,
     "    if epoch < start_epoch:\n        return 1.0",
     "    if epoch < start_epoch:\n        return 0.0", TRAINING, False, ("test_curriculum_and_schedules",)),
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


def failed_tests(output: str) -> list[str]:
    """The tests a run reports as failed: pytest's `FAILED path::name` summary
    lines and cargo's `---- name stdout ----` headers."""
    names = re.findall(r"^FAILED \S+::(\S+)", output, re.MULTILINE)
    names += re.findall(r"^---- (\S+) stdout ----", output, re.MULTILINE)
    return [n.split("::")[-1] for n in names]


def run_tests(cmd: list[str], timeout: int) -> tuple[str, list[str], float]:
    """("passed" | "failed" | "error" | "timeout", the failed tests, seconds).
    "failed" means at least one test ran and failed; any other non-zero exit
    (a collection error, a missing binary, a crash before any test) is an
    "error", which proves nothing about the mutant."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "train_py")}
    env.setdefault("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return "timeout", [], time.perf_counter() - t0
    secs = time.perf_counter() - t0
    output = p.stdout + p.stderr
    if "could not compile" in p.stderr or "SyntaxError" in output:
        raise RuntimeError(f"the mutant does not build, so it proves nothing: {cmd}")
    if p.returncode == 0:
        return "passed", [], secs
    failed = failed_tests(output)
    if not failed or re.search(r"^ERROR ", output, re.MULTILINE):
        return "error", failed, secs
    return "failed", failed, secs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--ci", action="store_true", help="only the fixed subset that `make test` runs")
    ap.add_argument("-k", dest="match", default="", help="only the mutants whose name contains this text")
    ap.add_argument("--timeout", type=int, default=900, help="seconds per mutant's test run")
    args = ap.parse_args(argv)
    chosen = [m for m in MUTANTS if (m[5] or not args.ci) and args.match in m[0]]
    for name, rel, old, *_ in chosen:
        count = (ROOT / rel).read_text().count(old)
        if count != 1:
            print(f"error: mutant `{name}`: the original text occurs {count} times in {rel}")
            return 2
    # A green baseline first: each command, as the mutants will run it, on the
    # unmutated source. A command that fails there would "catch" every mutant.
    commands = {tuple(mutated_crate_at_opt_level_0(m[4], m[1])) for m in chosen}
    for cmd in sorted(commands):
        outcome, failed, secs = run_tests(list(cmd), args.timeout)
        if outcome != "passed":
            print(f"error: the unmutated source does not pass ({outcome}: {failed}): {' '.join(cmd)}")
            return 2
        if not args.json:
            print(f"green    {' '.join(cmd[-4:])} ({secs:.0f} s)", flush=True)
    results = []
    for name, rel, old, new, cmd, _, expect in chosen:
        path = ROOT / rel
        original = path.read_text()
        try:
            path.write_text(original.replace(old, new))
            outcome, failed, secs = run_tests(mutated_crate_at_opt_level_0(cmd, rel), args.timeout)
        finally:
            path.write_text(original)
        # Caught only when the test written for this mutant is among those failing.
        caught = outcome == "failed" and any(e == f for e in expect for f in failed)
        results.append(
            {"mutant": name, "file": rel, "outcome": outcome, "failed_tests": failed, "expected": list(expect),
             "caught": caught, "seconds": round(secs, 1)}
        )  # fmt: skip
        if not args.json:
            why = "" if caught else f" [{outcome}; failed {failed or 'nothing'}, expected one of {list(expect)}]"
            print(f"{'caught ' if caught else 'MISSED '} {name} ({rel}, {secs:.0f} s){why}", flush=True)
    missed = [r for r in results if not r["caught"]]
    if args.json:
        print(json.dumps({"mutants": results, "caught": len(results) - len(missed), "missed": len(missed)}))
    else:
        print(f"{len(results) - len(missed)} of {len(results)} mutants caught by their tests")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
