"""A small, untrained model package plus reference inputs and the outputs
Python onnxruntime gives on them: the contract test of the Rust runtime.

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
    print(f"wrote fixture package and reference outputs to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
