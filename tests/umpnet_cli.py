"""The `umpnet` binary under test, for the end-to-end suites (tests/test_cli_*.py)."""

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UMPNET = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
# The default model package: the one the wheel ships (its `model` link), which
# the binary also finds by default (test_the_binary_and_the_wheel_default_to_one_package).
SHIPPED = (ROOT / "crates" / "py" / "python" / "umpnet" / "model").resolve()


def run(*args, check=True):
    p = subprocess.run([UMPNET, *args], check=False, capture_output=True, text=True, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"umpnet {' '.join(args)} exited {p.returncode}: {p.stderr}")
    return p
