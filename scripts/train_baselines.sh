#!/usr/bin/env bash
# umpnet and the paper's baselines trained with one recipe and one budget:
# cpu-small, reference physics, released labels, --dense-labels 16, seed 0,
# $EPOCHS epochs each (default 300), one variant after another. An estimated
# 45 minutes per variant on 2 cores (9 s per epoch, measured in a fine-tune).
#
# Resumable across sessions: each run lives in runs/budget/VARIANT (a
# checkpoint every 50 epochs). `scripts/train_baselines.sh keep` copies the
# runs' checkpoints to models/checkpoints/baselines/VARIANT/, to be committed
# (a finished variant is kept automatically). A run with no checkpoint in
# runs/ starts from the committed one. A resume starts with an empty replay
# buffer (the buffer is too large to commit).
#
# When every variant has reached $EPOCHS, `scripts/train_baselines.sh ship`
# writes the packages to models/baselines (where2act twice: with and without
# its 90-degree filter) and models/baselines/umpnet-300.
set -euo pipefail
cd "$(dirname "$0")/.."
EPOCHS=${EPOCHS:-300}
VARIANTS=${VARIANTS:-umpnet single-step aot-only signed-dist where2act inverse}
PY=$PWD/.venv/bin/python

kept() { echo "models/checkpoints/baselines/$1"; }
epoch_of() { "$PY" -c "import sys, torch; print(torch.load(sys.argv[1], weights_only=False)['epoch'])" "$1"; }

keep() {  # copy a run's checkpoint beside the others, to be committed
    local v=$1
    if [ -f "runs/budget/$v/checkpoint.pt" ]; then
        mkdir -p "$(kept "$v")"
        cp "runs/budget/$v/checkpoint.pt" "$(kept "$v")/checkpoint.pt.tmp"
        mv "$(kept "$v")/checkpoint.pt.tmp" "$(kept "$v")/checkpoint.pt"
    fi
}

if [ "${1:-train}" = keep ]; then
    for v in $VARIANTS; do keep "$v"; done
    exit 0
fi

if [ "${1:-train}" = ship ]; then
    for v in $VARIANTS; do
        ck=$(kept "$v")/checkpoint.pt
        [ -f "$ck" ] && [ "$(epoch_of "$ck")" = "$EPOCHS" ] || { echo "error: $ck has not reached epoch $EPOCHS" >&2; exit 1; }
    done
    for v in $VARIANTS; do
        dest=models/baselines/$v
        [ "$v" = umpnet ] && dest=models/baselines/umpnet-$EPOCHS
        (cd train_py && "$PY" -m umpnet_train.export "../$(kept "$v")/checkpoint.pt" "../$dest")
        if [ "$v" = where2act ]; then
            (cd train_py && "$PY" -m umpnet_train.export "../$(kept "$v")/checkpoint.pt" ../models/baselines/where2act-normal90 --direction-filter normal90)
        fi
    done
    exit 0
fi

for v in $VARIANTS; do
    out=runs/budget/$v
    mkdir -p "$out"
    if [ ! -f "$out/checkpoint.pt" ] && [ -f "$(kept "$v")/checkpoint.pt" ]; then
        cp "$(kept "$v")/checkpoint.pt" "$out/checkpoint.pt"
    fi
    resume=()
    if [ -f "$out/checkpoint.pt" ]; then
        [ "$(epoch_of "$out/checkpoint.pt")" = "$EPOCHS" ] && { echo "$v: done ($EPOCHS epochs)"; continue; }
        resume=(--resume)
    fi
    # The paper trains Inverse on the policy's own moves: the shipped model's.
    data=()
    [ "$v" = inverse ] && data=(--inverse-data ../models/umpnet-small)
    echo "$v: training to epoch $EPOCHS ${resume[*]} ${data[*]}"
    (cd train_py && "$PY" -m umpnet_train.train --preset cpu-small --dense-labels 16 --variant "$v" --seed 0 \
        --epochs "$EPOCHS" --out "../$out" "${data[@]}" "${resume[@]}")
    keep "$v"
done
