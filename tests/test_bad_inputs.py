"""The bad-input corpus: one file per kind of hostile input in tests/bad_inputs/,
each case run through the CLI or Python under a memory cap and a deadline.

A case passes when the process ends within its deadline, under the address-space
cap, without a panic, with the exit status the case names and the message it
must give. A blowup hits the cap (and fails the case) instead of the machine; a
hang hits the deadline.

Case fields (see any file for examples):
- `setup`: steps run here first, in a fresh folder ($TMP): `render`, `write`,
  `repeat` (a head and a line repeated), `fifo`, `symlink`, `copy`, `json`
  (set dotted keys), `poison` (a copy of the shipped package whose output is
  multiplied by a value, conftest.py's `poisoned_package`), `exec` (Python with TMP, REPO, np).
- `cli` with `exit` and `stderr`, and optionally `stdout` (a file to write it
  to, e.g. /dev/full), `interrupt_after` (seconds before SIGINT), `fsize`
  (the largest file it may write, as on a full disk) and `leaves_no` (globs
  under $TMP that must match nothing afterwards); or
- `python` with `raises` (an exception type name, or null for none) and `match`.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from umpnet_cli import ROOT, UMPNET

CORPUS = sorted((ROOT / "tests" / "bad_inputs").glob("*.json"))
# Each case's process: at most this much address space and this long. A run
# that would have taken gigabytes fails here instead of exhausting the machine.
MEMORY_CAP = 3 << 30
DEADLINE_S = 120

HARNESS = """
import sys
try:
    exec(compile(sys.argv[1], "<case>", "exec"), {"__name__": "__case__"})
except BaseException as e:
    print(f"RAISED {type(e).__name__}: {e}", file=sys.stderr)
    sys.exit(3)
"""


def subst(value, tmp: Path):
    if isinstance(value, str):
        return value.replace("$TMP", str(tmp)).replace("$REPO", str(ROOT))
    if isinstance(value, list):
        return [subst(v, tmp) for v in value]
    return value


def set_dotted(path: Path, changes: dict):
    data = json.loads(path.read_text())
    for key, value in changes.items():
        *parents, last = key.split(".")
        node = data
        for p in parents:
            node = node[p]
        node[last] = value
    path.write_text(json.dumps(data))


def setup(steps, tmp: Path, poisoned_package):
    for step in steps:
        kind, target = next(iter(step.items()))
        path = tmp / subst(target, tmp)
        if kind not in ("render", "copy", "poison"):
            path.parent.mkdir(parents=True, exist_ok=True)
        if kind == "render":
            cmd = [UMPNET, "render", *step.get("args", []), "--out", str(path)]
            subprocess.run(cmd, check=True, capture_output=True, timeout=DEADLINE_S)
        elif kind == "write":
            path.write_text(subst(step["text"], tmp))
        elif kind == "repeat":
            path.write_text(step["head"] + step["line"] * step["count"])
        elif kind == "fifo":
            os.mkfifo(path)
        elif kind == "symlink":
            path.symlink_to(subst(step["to"], tmp))
        elif kind == "copy":
            shutil.copytree(path, tmp / step["to"])
        elif kind == "json":
            set_dotted(path, step["set"])
        elif kind == "poison":
            shipped = ROOT / "models" / "umpnet-small"
            poisoned_package(shipped, path, step["file"], step["output"], float(step["value"]))
        elif kind == "exec":
            code = compile(subst(step["exec"], tmp), "<setup>", "exec")
            exec(code, {"TMP": tmp, "REPO": ROOT, "np": np})  # noqa: S102 (the corpus's own setup code)
        else:
            raise ValueError(f"unknown setup step {kind!r}")


def run_case(case, tmp: Path):
    if "cli" in case:
        cmd = [UMPNET, *subst(case["cli"], tmp)]
    else:
        cmd = [sys.executable, "-c", HARNESS, subst(case["python"], tmp)]
    out = open(case["stdout"], "w") if "stdout" in case else subprocess.PIPE  # noqa: SIM115
    try:
        # prlimit (util-linux) caps the address space of the process it starts.
        capped = ["prlimit", f"--as={MEMORY_CAP}", "--", *cmd]
        if "fsize" in case:
            # A disk that fills up: writes past `fsize` bytes fail (EFBIG). The
            # shell ignores SIGXFSZ first, and the ignored signal survives exec.
            capped = ["sh", "-c", 'trap "" XFSZ; exec "$@"', "sh", "prlimit", f"--fsize={case['fsize']}", *capped[1:]]
        p = subprocess.Popen(capped, stdout=out, stderr=subprocess.PIPE, cwd=ROOT, text=True)
        try:
            if "interrupt_after" in case:
                try:
                    p.wait(timeout=case["interrupt_after"])
                except subprocess.TimeoutExpired:
                    p.send_signal(signal.SIGINT)
            _, err = p.communicate(timeout=DEADLINE_S)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()
            pytest.fail(f"{cmd}: still running after {DEADLINE_S} s (a hang?)")
    finally:
        if out is not subprocess.PIPE:
            out.close()
    return p.returncode, err


def cases():
    for file in CORPUS:
        kind = json.loads(file.read_text())
        for case in kind["cases"]:
            yield pytest.param(kind, case, id=f"{file.stem}-{case['name']}")


def test_every_kind_of_the_issue_has_a_corpus_file():
    kinds = sorted(json.loads(f.read_text())["kind"] for f in CORPUS)
    assert kinds == list(range(1, 21)), kinds


@pytest.mark.parametrize("kind,case", list(cases()))
def test_bad_input_gets_its_error_within_memory_and_time(kind, case, tmp_path, poisoned_package):
    setup(case.get("setup", []), tmp_path, poisoned_package)
    code, err = run_case(case, tmp_path)
    assert "panicked" not in err and "PanicException" not in err, err[-2000:]
    if "cli" in case:
        assert code == case["exit"], (code, err[-2000:])
        if case.get("stderr"):
            assert case["stderr"] in err, err[-2000:]
        for pattern in case.get("leaves_no", []):
            left = sorted(str(p) for p in tmp_path.glob(pattern))
            assert not left, f"left behind: {left}"
    elif case["raises"] is None:
        assert code == 0, err[-2000:]
    else:
        assert code == 3, (code, err[-2000:])
        assert f"RAISED {case['raises']}:" in err and case["match"] in err, err[-2000:]
