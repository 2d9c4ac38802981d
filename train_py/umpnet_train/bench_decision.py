"""One full direction decision (encoders once, two decoder rounds of 64
candidates) through the Rust runtime (ONNX Runtime) and through the same
networks in PyTorch eager, on the same inputs, in the same run.

    python -m umpnet_train.bench_decision MODEL_DIR [--threads 1] [--repeats 50]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
import torch
import umpnet

from .config import Config, config_from_checkpoint
from .models import OBS_MEAN, UMPNet


def torch_model(package: Path) -> tuple[UMPNet, Config]:
    meta = json.loads((package / "model.json").read_text())
    cfg = config_from_checkpoint(meta["config"])
    return UMPNet(cfg).eval(), cfg


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("model", type=Path)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--repeats", type=int, default=50)
    p.add_argument("--random-weights", action="store_true", help="PyTorch side only needs shapes: compare speed")
    a = p.parse_args(argv)
    torch.set_num_threads(a.threads)
    model, cfg = torch_model(a.model)
    policy = umpnet.Policy(str(a.model), seed=0, threads=a.threads)
    rng = np.random.default_rng(0)
    h, w = cfg.height, cfg.width
    obs = (rng.normal(size=(1, h, w, 10)) * 0.3 + OBS_MEAN).astype(np.float32)
    ref = (rng.normal(size=(1, h, w, 10)) * 0.3 + OBS_MEAN).astype(np.float32)
    pix = np.array([[h // 2, w // 2]], dtype=np.int64)

    def rust():
        policy.direction_batch(obs, ref, pix, mode="explore")

    tobs, tref, tpix = torch.from_numpy(obs), torch.from_numpy(ref), torch.from_numpy(pix)

    @torch.no_grad()
    def eager():
        de, ae = model.encoder(tobs, tref, tpix)
        cand = torch.nn.functional.normalize(torch.randn(64, 3), dim=1)
        dist, logits = model.decoder(de.expand(64, -1), ae.expand(64, -1), cand)
        score = torch.where(logits.argmax(1) == 2, dist, torch.zeros_like(dist))
        weights = torch.softmax(20 * score, 0)
        idx = torch.multinomial(weights, 64, replacement=True)
        cand2 = torch.nn.functional.normalize(cand[idx] + 0.1 * torch.randn(64, 3), dim=1)
        model.decoder(de.expand(64, -1), ae.expand(64, -1), cand2)

    results = {}
    for name, fn in [("onnxruntime (Rust)", rust), ("pytorch eager", eager)]:
        for _ in range(5):
            fn()
        times = []
        for _ in range(a.repeats):
            t0 = time.perf_counter()
            fn()
            times.append((time.perf_counter() - t0) * 1e3)
        results[name] = statistics.median(times)
    ort_ms, torch_ms = results["onnxruntime (Rust)"], results["pytorch eager"]
    print(f"one decision at {h}x{w}, {a.threads} thread(s), median of {a.repeats}:")
    print(f"  onnxruntime (Rust runtime) {ort_ms:7.2f} ms")
    print(f"  PyTorch eager              {torch_ms:7.2f} ms")
    print(f"  speed-up                   {torch_ms / ort_ms:7.2f}x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
