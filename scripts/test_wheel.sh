#!/usr/bin/env bash
# Build the abi3 wheel, install it with its dependencies in a fresh venv
# outside the repository, and run tests/wheel/smoke.py there.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/umpnet-wheel.XXXXXX")
trap 'rm -rf "$work"' EXIT
(cd "$repo/crates/py" && "$repo/.venv/bin/maturin" build --release -q -o "$work/dist")
wheel=$(ls "$work"/dist/umpnet-*.whl)
python3 -m venv "$work/venv"
"$work/venv/bin/python" -m pip install -q --disable-pip-version-check "${wheel}[gym]"
# From the temporary folder: nothing of the repository is importable.
cd "$work"
env -u PYTHONPATH -u ORT_DYLIB_PATH "$work/venv/bin/python" "$repo/tests/wheel/smoke.py" "$repo"
"$work/venv/bin/python" -m pip list --disable-pip-version-check 2>/dev/null | grep -iE '^(umpnet|onnxruntime|numpy|gymnasium) '
