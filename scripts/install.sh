#!/usr/bin/env bash
# Idempotent installer for a fresh Debian machine: apt packages only when
# missing, Python packages into the repo's .venv only when missing.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
for pkg in mesa-vulkan-drivers libvulkan1 fonts-dejavu-core; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ]; then
  echo "install: apt packages ${need_apt[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  echo "install: creating .venv"
  python3 -m venv .venv
fi
# `install.sh runtime` (make demo, make build): what the binary needs, no PyTorch.
# `install.sh` (make test, training): everything.
what=${1:-all}
case "$what" in
  runtime) reqs=requirements/runtime.txt ;;
  all) reqs=train_py/requirements.txt ;;
  *) echo "install.sh: expected 'runtime' or 'all', got '$what'" >&2; exit 2 ;;
esac
stamp=.venv/.umpnet-requirements-$what
if [ ! -f "$stamp" ] || ! cat "$reqs" requirements/runtime.txt | cmp -s - "$stamp"; then
  echo "install: Python packages from $reqs"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -r "$reqs"
  cat "$reqs" requirements/runtime.txt > "$stamp"
fi
