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
stamp=.venv/.umpnet-requirements
if [ ! -f "$stamp" ] || ! cmp -s train_py/requirements.txt "$stamp"; then
  echo "install: Python packages from train_py/requirements.txt"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -r train_py/requirements.txt
  cp train_py/requirements.txt "$stamp"
fi
