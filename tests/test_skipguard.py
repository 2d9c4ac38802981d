"""The skip guard `make test` loads: under CI=true an unexpected skip fails the run."""

import os
import subprocess
import sys
from pathlib import Path

PLUGINS = Path(__file__).resolve().parent / "plugins"


def _run(tmp_path, **env):
    (tmp_path / "test_one.py").write_text(
        "import pytest\n\ndef test_skipped():\n    pytest.skip('no device here')\n\ndef test_ran():\n    pass\n"
    )
    base = {k: v for k, v in os.environ.items() if k not in ("CI", "UMPNET_EXPECTED_SKIPS", "PYTEST_ADDOPTS")}
    p = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "skipguard", str(tmp_path)],
        env={**base, "PYTHONPATH": str(PLUGINS), **env},
        capture_output=True,
        text=True,
        check=False,
    )
    return p.returncode, p.stdout


def test_an_unexpected_skip_fails_under_ci_and_an_expected_one_does_not(tmp_path):
    code, out = _run(tmp_path, CI="true")
    assert code == 1 and "unexpected skip under CI=true" in out and "no device here" in out, out
    assert _run(tmp_path, CI="true", UMPNET_EXPECTED_SKIPS="other;no device")[0] == 0
    assert _run(tmp_path)[0] == 0  # outside CI a skip is shown and counted, not an error
