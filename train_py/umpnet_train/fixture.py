"""A small, untrained model package plus reference inputs and the outputs
Python onnxruntime gives on them: the contract test of the Rust runtime.
Beside it, packages whose decoder is set by hand, for the tests of what the
runtime's choices mean (OUT_DIR/steer, steer-normal90 and inverse).

    python -m umpnet_train.fixture OUT_DIR
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import onnxruntime as ort
import torch

from .config import make_config
from .export import export_model
from .models import CHANNELS, OBS_MEAN, UMPNet


def unit_rows(d: np.ndarray) -> np.ndarray:
    return d / np.linalg.norm(d, axis=1, keepdims=True)


CANONICAL = (-1, 0, 1)


def steering_model(columns=CANONICAL):
    """A smoke model whose decoder ignores the image: distance 0.3 - 0.2 x, and
    AoT logits 10 x for class +1, -10 x for -1, 1 for 0 (no move when |x| < 0.1).
    So the distance head rates -x highest while the AoT head calls +x forward.
    `columns` is the class each output column holds."""
    torch.manual_seed(0)
    cfg = make_config("smoke")
    model = UMPNet(cfg)
    dec = model.decoder
    with torch.no_grad():
        for p in dec.parameters():
            p.zero_()
        dec.dist_head[-1].bias.fill_(0.3)
        dec.bilinear_dist.bias.copy_(torch.tensor([-0.2, 0.0, 0.0]))
        bil, base = torch.zeros(3, 3), torch.zeros(3)
        for col, cls in enumerate(columns):
            bil[col, 0] = 10.0 * cls
            base[col] = 1.0 if cls == 0 else 0.0
        dec.bilinear_aot.bias.copy_(bil.reshape(-1))
        dec.aot_head[-1].bias.copy_(base)
    return model, cfg


def inverse_model(prediction=(1.2, 1.6, 0.0)):
    """An Inverse-baseline smoke model that regresses `prediction` whatever it sees."""
    torch.manual_seed(0)
    cfg = make_config("smoke", variant="inverse")
    model = UMPNet(cfg)
    with torch.no_grad():
        for p in model.decoder.inverse_head.parameters():
            p.zero_()
        model.decoder.inverse_head[-1].bias.copy_(torch.tensor(prediction))
    return model, cfg


def constant_joint_net(height: int, width: int):
    """A JointNet whose every pixel says: movable, a slide along +x (its
    weights zero, its head's bias set), so the runtime's vote is known."""
    from .joint_net import OUTPUTS, JointConfig, JointNet

    cfg = JointConfig(height=height, width=width, widths=(4, 8))
    model = JointNet(cfg)
    with torch.no_grad():
        for p in model.parameters():
            p.zero_()
        bias = dict.fromkeys(OUTPUTS, 0.0) | {"movable": 5.0, "revolute": -5.0, "flow_x": 1.0, "axis_x": 1.0}
        model.unet.head.bias.copy_(torch.tensor([bias[k] for k in OUTPUTS]))
    return model, cfg


def write_hand_set_packages(out: Path) -> None:
    provenance = {"command": "python -m umpnet_train.fixture", "seed": 0, "trained": False}
    model, cfg = steering_model()
    export_model(model, cfg, out / "steer", provenance)
    export_model(model, cfg, out / "steer-normal90", provenance, direction_filter="normal90")
    model, cfg = inverse_model()
    export_model(model, cfg, out / "inverse", provenance)
    # The steering package with a JointNet that always votes a slide along +x.
    model, cfg = steering_model()
    export_model(model, cfg, out / "joint", provenance)
    from .joint_net import export_joint

    export_joint(*constant_joint_net(cfg.height, cfg.width), out / "joint")


def main(argv=None) -> int:
    out = Path((argv or sys.argv[1:])[0])
    torch.manual_seed(0)
    cfg = make_config("smoke")
    model = UMPNet(cfg)
    export_model(model, cfg, out, {"command": "python -m umpnet_train.fixture", "seed": 0, "trained": False})
    rng = np.random.default_rng(0)
    h, w, e = cfg.height, cfg.width, cfg.embedding
    feeds = {
        "position.onnx": {"observation": (rng.normal(size=(2, h, w, CHANNELS)) * 0.5 + OBS_MEAN).astype(np.float32)},
        "direction_encoder.onnx": {
            "observation": (rng.normal(size=(3, h, w, CHANNELS)) * 0.5 + OBS_MEAN).astype(np.float32),
            "reference": (rng.normal(size=(3, h, w, CHANNELS)) * 0.5 + OBS_MEAN).astype(np.float32),
            "pixel": np.array([[0, 0], [h // 2, w // 2], [h - 1, w - 1]], dtype=np.int64),
        },
        "direction_decoder.onnx": {
            "dist_embedding": rng.normal(size=(7, e)).astype(np.float32),
            "aot_embedding": rng.normal(size=(7, e)).astype(np.float32),
            "direction": unit_rows(rng.normal(size=(7, 3))).astype(np.float32),
        },
    }
    manifest = []
    ref_dir = out / "reference"
    ref_dir.mkdir(exist_ok=True)
    for model_file, inputs in feeds.items():
        sess = ort.InferenceSession(str(out / model_file), providers=["CPUExecutionProvider"])
        outputs = sess.run(None, inputs)
        names = [o.name for o in sess.get_outputs()]
        entry = {"model": model_file, "inputs": [], "outputs": []}
        for kind, items in [("inputs", inputs.items()), ("outputs", zip(names, outputs))]:
            for name, arr in items:
                file = f"{model_file.split('.')[0]}.{name}.bin"
                arr.tofile(ref_dir / file)
                entry[kind].append({"name": name, "file": file, "shape": list(arr.shape), "dtype": str(arr.dtype)})
        manifest.append(entry)
    (ref_dir / "manifest.json").write_text(json.dumps(manifest, indent=2))
    write_hand_set_packages(out)
    print(f"wrote fixture package and reference outputs to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
