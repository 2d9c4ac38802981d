#!/usr/bin/env bash
# Trains on a lent GPU machine for a fixed wall time, then leaves the
# checkpoints where they can be taken home (docs/training.md, "On a GPU").
#
#   scripts/device_train.sh OUT SECONDS
#
# Two runs share the machine: the JointNet (a wider U-Net, its frames made by
# worker processes, all of them kept on the GPU) and the direction networks of
# the gpu-medium preset (the shipped package's position net, frozen). Both
# stop with a checkpoint at SECONDS; the packages are exported at home, where
# the runtime's ONNX Runtime checks them. The machine needs python3 with
# PyTorch and the umpnet bindings on PYTHONPATH (crates/py/python, with the
# extension built at home: it is abi3, so any Python >= 3.9 loads it). Set
# UMPNET_GIT_COMMIT to the commit sent: the copy there may hold a stale .git.
# TRAIN_ARGS adds flags to the policy run (e.g. TRAIN_ARGS="--mirror 0.25"),
# JOINT_ARGS to the JointNet's (e.g. JOINT_ARGS="--mirror 0.5"). POSITION_FROM
# names the checkpoint whose position net the policy run takes, frozen (default:
# the shipped umpnet-small's); set it empty to train the position net as well,
# from scratch or from the checkpoint `--resume` reads (the grasp must train
# for it to learn from TRAIN_ARGS="--glass-depth-mix P").
#
# The lent machine takes the working tree and carried paths up to 64 MiB:
# carry the extension (crates/py/python/umpnet/_umpnet.abi3.so, 11 MB after
# `strip --strip-unneeded`) and, to resume, the run's folder under runs/.
set -uo pipefail
out=${1:?usage: scripts/device_train.sh OUT SECONDS}
seconds=${2:?usage: scripts/device_train.sh OUT SECONDS}
root=$(cd "$(dirname "$0")/.." && pwd)
export PYTHONPATH="$root/crates/py/python:$root/train_py${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
mkdir -p "$out/policy" "$out/joint"

# Fails in seconds, not after the budget, when the machine lacks something.
python3 - <<'EOF' || exit 3
import torch, umpnet
env = umpnet.VecEnv(2, category="Refrigerator", split="train", resolution=(96, 128), renderer="cpu")
env.reset()
print(f"umpnet {umpnet.__version__}, torch {torch.__version__}, cuda {torch.cuda.is_available()}"
      f" ({torch.cuda.get_device_name() if torch.cuda.is_available() else 'none'})", flush=True)
EOF

python3 -m umpnet_train.joint_net --out "$out/joint" --device auto --workers 8 \
  --frames "${FRAMES:-24000}" --steps 12000 --batch 48 --widths 24,48,96,192 --time-limit "$seconds" \
  ${JOINT_ARGS:-} >"$out/joint.log" 2>&1 &
joint=$!
position_from=${POSITION_FROM-$root/models/checkpoints/umpnet-small/checkpoint.pt}
python3 -m umpnet_train.train --preset gpu-medium --dense-labels 16 --renderer cpu --device auto \
  ${position_from:+--position-from "$position_from"} \
  --out "$out/policy" --time-limit "$seconds" ${TRAIN_ARGS:-} >"$out/policy.log" 2>&1
policy_rc=$?
wait $joint
joint_rc=$?
echo "policy exit $policy_rc, joint exit $joint_rc"
tail -n 4 "$out/policy.log" "$out/joint.log"
[ "$policy_rc" = 0 ] && [ "$joint_rc" = 0 ]
