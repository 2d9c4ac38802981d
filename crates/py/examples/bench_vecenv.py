"""Environment steps per second of umpnet.VecEnv (one step = one direction
action plus a fresh observation on every environment).

    python crates/py/examples/bench_vecenv.py [--renderer wgpu|cpu] [--resolution 120x160]
"""

import argparse
import json
import time

import numpy as np
import umpnet


def measure(n, resolution, renderer, steps=30):
    env = umpnet.VecEnv(n, seed=0, resolution=resolution, renderer=renderer)
    env.reset()
    env.step_position(np.array(env.scripted_actions("oracle"), dtype=np.int64))
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(steps):
        d = rng.normal(size=(n, 3)).astype(np.float32)
        env.step_direction(d / np.linalg.norm(d, axis=1, keepdims=True))
    return n * steps / (time.perf_counter() - t0)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--renderer", default="auto")
    p.add_argument("--resolution", default="120x160")
    p.add_argument("--sizes", default="1,2,4,16")
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    res = tuple(int(v) for v in a.resolution.split("x"))
    rows = [{"n": n, "steps_per_s": measure(n, res, a.renderer)} for n in map(int, a.sizes.split(","))]
    if a.json:
        print(json.dumps(rows))
    else:
        print(f"VecEnv at {res[0]}x{res[1]}, renderer {a.renderer}")
        for r in rows:
            print(f"  n={r['n']:>3}  {r['steps_per_s']:8.1f} env steps/s")


if __name__ == "__main__":
    main()
