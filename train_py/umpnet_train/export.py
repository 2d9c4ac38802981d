"""Export a checkpoint as a model package the Rust runtime loads
(contract: docs/model-package.md), checking ONNX against PyTorch.

    python -m umpnet_train.export CKPT OUT_DIR
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import torch
from torch import nn

from .config import Config, config_from_checkpoint
from .models import CHANNELS, OBS_MEAN, OBS_STD, UMPNet, uses_reference

FORMAT_VERSION = 1
MAX_ABS_DIFF = 1e-3


class PositionExport(nn.Module):
    def __init__(self, net):
        super().__init__()
        self.net = net

    def forward(self, observation):
        return torch.softmax(self.net(observation), dim=1)[:, 1]


class EncoderExport(nn.Module):
    def __init__(self, enc):
        super().__init__()
        self.enc = enc

    def forward(self, observation, reference, pixel):
        return self.enc(observation, reference, pixel)


class InverseDecoderExport(nn.Module):
    """The Inverse baseline's decoder: no candidate direction in, one unit direction out."""

    def __init__(self, dec):
        super().__init__()
        self.dec = dec

    def forward(self, dist_embedding, aot_embedding):
        return torch.nn.functional.normalize(self.dec.inverse(dist_embedding, aot_embedding), dim=1)


class DecoderExport(nn.Module):
    def __init__(self, dec, variant):
        super().__init__()
        self.dec, self.variant = dec, variant

    def forward(self, dist_embedding, aot_embedding, direction):
        distance, logits = self.dec(dist_embedding, aot_embedding, direction)
        # Variants that ignore one embedding still take it: the contract has three inputs
        # and the exporter would otherwise prune the unused one.
        if self.variant == "aot-only":
            return torch.softmax(logits, dim=1) + 0.0 * dist_embedding.sum(dim=1, keepdim=True)
        if self.variant == "signed-dist":
            return distance + 0.0 * aot_embedding.sum(dim=1)
        if self.variant == "where2act":
            return torch.sigmoid(distance) + 0.0 * aot_embedding.sum(dim=1)
        # A joint change is never negative; the regression can undershoot zero.
        return distance.clamp(min=0.0), torch.softmax(logits, dim=1)


def decoder_outputs(variant: str) -> list[str]:
    special = {
        "aot-only": ["aot_probs"],
        "signed-dist": ["signed_distance"],
        "where2act": ["success_prob"],
        "inverse": ["predicted_direction"],
    }
    return special.get(variant, ["distance", "aot_probs"])


def branches(variant: str) -> list[str]:
    special = {"aot-only": ["aot"], "signed-dist": ["signed_dist"], "where2act": ["binary"], "inverse": ["inverse"]}
    return special.get(variant, ["dist", "aot"])


def _export(module, args, path, inputs, outputs, dynamic):
    # The exporter restores the wrapper's mode afterwards, recursively: keep it in eval.
    module.eval()
    torch.onnx.export(
        module,
        args,
        str(path),
        input_names=inputs,
        output_names=outputs,
        dynamic_axes=dynamic,
        opset_version=17,
        dynamo=False,
    )


def signed_distance_threshold(labels: str) -> float:
    """Where the runtime splits a SignedDist prediction into "moved" and
    "no effective change": halfway between the label of no move (0) and the
    smallest move the training labels count (0.05 m with the reference's
    thresholds, δ = 0.15 with the paper text's)."""
    return {"reference": 0.05, "delta": 0.15}[labels] / 2


def export_model(
    model: UMPNet,
    cfg: Config,
    out: Path,
    provenance: dict,
    evaluation: dict | None = None,
    direction_filter: str = "none",
) -> float:
    """Writes the package; returns the largest |ONNX - PyTorch| over all outputs."""
    import onnxruntime as ort

    out.mkdir(parents=True, exist_ok=True)
    model = model.eval().cpu()
    h, w, e = cfg.height, cfg.width, cfg.embedding
    g = torch.Generator().manual_seed(0)
    obs = torch.randn(2, h, w, CHANNELS, generator=g) * 0.5 + torch.tensor(OBS_MEAN)
    ref = torch.randn(2, h, w, CHANNELS, generator=g) * 0.5 + torch.tensor(OBS_MEAN)
    pixel = torch.tensor([[h // 2, w // 3], [h - 1, 0]], dtype=torch.int64)
    de = torch.randn(5, e, generator=g)
    ae = torch.randn(5, e, generator=g)
    direction = torch.nn.functional.normalize(torch.randn(5, 3, generator=g), dim=1)
    dec_out = decoder_outputs(cfg.variant)
    with torch.no_grad():
        _export(
            PositionExport(model.position),
            (obs,),
            out / "position.onnx",
            ["observation"],
            ["affordance"],
            {"observation": {0: "batch"}, "affordance": {0: "batch"}},
        )
        _export(
            EncoderExport(model.encoder),
            (obs, ref, pixel),
            out / "direction_encoder.onnx",
            ["observation", "reference", "pixel"],
            ["dist_embedding", "aot_embedding"],
            {k: {0: "batch"} for k in ["observation", "reference", "pixel", "dist_embedding", "aot_embedding"]},
        )
        inverse = cfg.variant == "inverse"
        decoder = InverseDecoderExport(model.decoder) if inverse else DecoderExport(model.decoder, cfg.variant)
        dec_in = {"dist_embedding": de, "aot_embedding": ae} | ({} if inverse else {"direction": direction})
        _export(
            decoder,
            tuple(dec_in.values()),
            out / "direction_decoder.onnx",
            list(dec_in),
            dec_out,
            {k: {0: "candidates"} for k in [*dec_in, *dec_out]},
        )
        model.eval()
        expected = {
            "position.onnx": ([PositionExport(model.position)(obs)], {"observation": obs}),
            "direction_encoder.onnx": (
                list(EncoderExport(model.encoder)(obs, ref, pixel)),
                {"observation": obs, "reference": ref, "pixel": pixel},
            ),
        }
        dec = decoder(*dec_in.values())
        expected["direction_decoder.onnx"] = (list(dec) if isinstance(dec, tuple) else [dec], dec_in)
    worst = 0.0
    for name, (torch_out, feeds) in expected.items():
        sess = ort.InferenceSession(str(out / name), providers=["CPUExecutionProvider"])
        onnx_out = sess.run(None, {k: v.numpy() for k, v in feeds.items()})
        for a, b in zip(torch_out, onnx_out):
            worst = max(worst, float(np.abs(a.numpy() - b).max()))
            if float(np.abs(a.numpy() - b).max()) > MAX_ABS_DIFF:
                print(f"{name}: output differs by {float(np.abs(a.numpy() - b).max()):.2e}", file=sys.stderr)
    meta = {
        "format": "umpnet-model",
        "version": FORMAT_VERSION,
        "variant": cfg.variant,
        "input": {
            "height": h,
            "width": w,
            "channels": CHANNELS,
            "layout": "NHWC float32",
            "channel_order": ["x", "y", "z", "r", "g", "b", "nx", "ny", "nz", "depth"],
            "normalisation": {"mean": OBS_MEAN, "std": OBS_STD, "applied": "inside the networks"},
        },
        "embedding": e,
        "branches": branches(cfg.variant),
        "uses_reference": uses_reference(cfg.variant),
        "direction_filter": direction_filter,
        "aot_classes": [-1, 0, 1],
        "signed_distance_threshold": signed_distance_threshold(cfg.labels),
        "files": {
            "position": "position.onnx",
            "direction_encoder": "direction_encoder.onnx",
            "direction_decoder": "direction_decoder.onnx",
        },
        "decoder_outputs": dec_out,
        "config": {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(cfg).items()},
        "provenance": provenance,
        "evaluation": evaluation or {},
        "export_check": {"max_abs_diff_onnx_vs_torch": worst},
    }
    (out / "model.json").write_text(json.dumps(meta, indent=2))
    if worst > MAX_ABS_DIFF:
        raise RuntimeError(f"ONNX and PyTorch disagree by {worst:.2e} (> {MAX_ABS_DIFF})")
    return worst


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("checkpoint", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument(
        "--direction-filter",
        choices=["none", "normal90", "prev90"],
        default="none",
        help="normal90: the runtime keeps only directions within 90 degrees of the surface normal (Where2Act); "
        "prev90: within 90 degrees of the previous action (the paper's +HP, exploration only)",
    )
    a = p.parse_args(argv)
    if not a.checkpoint.is_file():
        print(f"error: {a.checkpoint}: no such checkpoint", file=sys.stderr)
        return 2
    ck = torch.load(a.checkpoint, map_location="cpu", weights_only=False)
    cfg = config_from_checkpoint(ck["config"])
    model = UMPNet(cfg)
    model.load_state_dict(ck["model"])
    worst = export_model(model, cfg, a.out, ck.get("provenance", {}), ck.get("evaluation"), a.direction_filter)
    print(f"wrote {a.out} (max |ONNX - PyTorch| = {worst:.2e})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
