"""Weight interpolation between a checkpoint and its own fine-tune (beyond
the paper; WiSE-FT, Wortsman et al., CVPR 2022).

A fine-tune gains where it trained and can lose on what it never saw: the
grasp fine-tuned on misread glass (models/checkpoints/umpnet-gpu-medium-grasp)
gained on the test categories and lost on LIBERO's objects. Both ends start
from the same weights, so the straight line between them stays in one basin,
and points on it often keep most of the fine-tune's gains and little of its
losses. This writes the checkpoint whose chosen networks are

    (1 - alpha) * BASE + alpha * FINETUNED

and whose other networks are BASE's. Integer buffers (BatchNorm's
`num_batches_tracked`) are BASE's. The checkpoint has no optimiser state: it
is a point nobody trained to.

    python -m umpnet_train.interpolate BASE.pt FINETUNED.pt OUT_DIR --alpha 0.5 --nets position
"""

from __future__ import annotations

import argparse
import copy
import os
import sys
from pathlib import Path

import torch

NETS = ("position", "encoder", "decoder")


class InterpolationError(ValueError):
    pass


def interpolate(base: dict, finetuned: dict, alpha: float, nets: tuple[str, ...]) -> tuple[dict, dict]:
    """The interpolated checkpoint (a new dict) and a summary: how many tensors
    were mixed, and how many of the networks left out differ between the two."""
    if not 0.0 <= alpha <= 1.0:
        raise InterpolationError(f"--alpha {alpha}: expected a weight between 0 and 1")
    unknown = [n for n in nets if n not in NETS]
    if unknown or not nets:
        raise InterpolationError(f"--nets {','.join(nets)}: expected some of {', '.join(NETS)}")
    a, b = base["model"], finetuned["model"]
    if a.keys() != b.keys():
        only = sorted(a.keys() ^ b.keys())
        raise InterpolationError(f"the checkpoints hold different networks (e.g. tensor {only[0]!r})")
    for k, v in a.items():
        if v.shape != b[k].shape:
            raise InterpolationError(
                f"tensor {k!r} is {tuple(v.shape)} in BASE and {tuple(b[k].shape)} in FINETUNED: not the same architecture"
            )
    mixed, left_out_differ = 0, 0
    model = {}
    for k, v in a.items():
        if k.split(".")[0] in nets and v.is_floating_point():
            model[k] = (1 - alpha) * v + alpha * b[k].to(v.dtype)
            mixed += 1
        else:
            model[k] = v.clone()
            left_out_differ += k.split(".")[0] not in nets and not torch.equal(v, b[k])
    out = {k: copy.deepcopy(v) for k, v in base.items() if k not in ("model", "optimizer", "scheduler")}
    out["model"] = model
    summary = {"tensors_mixed": mixed, "left_out_tensors_that_differ": int(left_out_differ)}
    provenance = out.setdefault("provenance", {})
    provenance.setdefault("segments", []).append(
        {
            "from_epoch": base.get("epoch"),
            "what": "weight interpolation (umpnet_train.interpolate, after WiSE-FT): the networks in `nets` are "
            "(1 - alpha) * this checkpoint's + alpha * those of `finetuned`, a fine-tune of it; the rest are this "
            "checkpoint's",
            "alpha": alpha,
            "nets": list(nets),
            "finetuned": {
                "epoch": finetuned.get("epoch"),
                "command": finetuned.get("provenance", {}).get("command"),
            },
            **summary,
        }
    )
    return out, summary


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("base", type=Path, help="the checkpoint the fine-tune started from")
    p.add_argument("finetuned", type=Path, help="the fine-tuned checkpoint")
    p.add_argument("out", type=Path, help="folder for checkpoint.pt")
    p.add_argument("--alpha", type=float, default=0.5, help="0: BASE, 1: FINETUNED (default 0.5, WiSE-FT's)")
    p.add_argument("--nets", default="position", help=f"comma-separated, of {', '.join(NETS)} (default: position)")
    p.add_argument("--force", action="store_true", help="replace OUT_DIR/checkpoint.pt if it exists")
    a = p.parse_args(argv)
    for path in (a.base, a.finetuned):
        if not path.is_file():
            print(f"error: {path}: no such checkpoint", file=sys.stderr)
            return 2
    target = a.out / "checkpoint.pt"
    if target.exists() and not a.force:
        print(f"error: {target} exists; pass --force to replace it", file=sys.stderr)
        return 2
    try:
        base, finetuned = (_load(x) for x in (a.base, a.finetuned))
        for path, ck in ((a.base, base), (a.finetuned, finetuned)):
            if not isinstance(ck, dict) or "model" not in ck:
                raise InterpolationError(f"{path}: not a umpnet_train checkpoint (no 'model')")
        if _architecture(base) != _architecture(finetuned):
            raise InterpolationError(f"{a.base} and {a.finetuned}: their configs name different networks")
        out, summary = interpolate(base, finetuned, a.alpha, tuple(n for n in a.nets.split(",") if n))
        out["provenance"]["segments"][-1]["finetuned"]["path"] = str(a.finetuned)
    except InterpolationError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    a.out.mkdir(parents=True, exist_ok=True)
    partial = target.with_suffix(".pt.partial")
    torch.save(out, partial)
    os.replace(partial, target)  # an interrupted write never leaves a half checkpoint under the name
    print(
        f"wrote {target}: {summary['tensors_mixed']} tensors at alpha {a.alpha}; "
        f"{summary['left_out_tensors_that_differ']} tensors of the other networks differ and were taken from BASE"
    )
    return 0


def _load(path: Path) -> dict:
    try:
        return torch.load(path, map_location="cpu", weights_only=False)
    except Exception as e:  # a truncated or foreign file: torch raises pickle's and zipfile's errors
        raise InterpolationError(f"{path}: not a readable checkpoint ({type(e).__name__}: {e})") from e


def _architecture(ck: dict) -> tuple:
    cfg = ck.get("config") or {}
    keys = ("height", "width", "position_widths", "direction_widths", "embedding", "action_embedding", "variant")
    return tuple(str(cfg.get(k)) for k in keys)


if __name__ == "__main__":
    sys.exit(main())
