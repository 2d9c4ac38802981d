"""umpnet beside the paper's simulator (PyBullet) on one URDF, in one run.

    .venv/bin/python benches/compare_pybullet.py [--repeats 15] [--json]

PyBullet and umpnet take turns, measurement by measurement, so that both see
the same machine load. Wall milliseconds, min / median:

- physics per 0.18 m action: the reference simulator of the differential
  suite (tests/reference/pybullet_sim.py) against `umpnet.Articulation`
  (reference physics), the same pulls on the same door;
- a 480x640 and a 120x160 observation. PyBullet's is `getCameraImage` alone,
  with its CPU renderer and with EGL, and nothing derived from it. umpnet's
  is the whole 10-channel tensor (points, colours, normals, depth) from
  `Env.observe()`. The comparison favours PyBullet;
- a 10-action episode at 480x640: the grasp and ten pulls, each followed by
  an observation;
- umpnet in Rust: the physics time `move_gripper` measures inside Rust for
  the same moves, and `umpnet bench --object` on the same file for the
  observations;
- `umpnet.VecEnv` actions per second at 120x160 for n = 1, 2, 4, 8, with
  batched rendering (the default) and with each environment drawing its own
  frame, taking turns;
- render agreement: umpnet's wgpu segmentation against its CPU renderer's,
  over the object's pixels.

The targets of the throughput issue are reported at the end (met or missed);
with `--check` a missed target makes the exit status 1. Run it on a quiet
machine: the ratios mean nothing beside a training run.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pkgutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pybullet as pb
import umpnet
from pybullet_utils import bullet_client

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "reference"))
from differential import CABINET_URDF, cabinet_cases
from pybullet_sim import ReferenceSim, StdoutToStderr

HI, LO = (480, 640), (120, 160)
OBJECT_SEGMENT = 1 << 16  # segmentation ids: 0 background, 1 floor, 2 gripper, 2**16 + part


def stats(ms):
    return {"min": float(np.min(ms)), "median": float(np.median(ms)), "n": len(ms)}


class PyBulletCamera:
    """The object in a PyBullet client, seen by umpnet's camera, with the CPU renderer or EGL."""

    def __init__(self, urdf, scene, world_from_camera, intrinsics, egl):
        self.bc = bullet_client.BulletClient(connection_mode=pb.DIRECT)
        if egl:
            plugin = pkgutil.get_loader("eglRenderer")
            if plugin is None or self.bc.loadPlugin(plugin.get_filename(), "_eglRendererPlugin") < 0:
                raise RuntimeError("pybullet's EGL renderer plugin does not load here")
        self.renderer = pb.ER_BULLET_HARDWARE_OPENGL if egl else pb.ER_TINY_RENDERER
        yaw = scene["base_yaw"]
        self.body = self.bc.loadURDF(
            urdf,
            basePosition=[*scene["base_xy"], 0.0],
            baseOrientation=[0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)],
            useFixedBase=True,
        )
        # OpenCV camera axes (x right, y down, z forward) to PyBullet's look-at.
        t = np.asarray(world_from_camera)
        eye = t[:3, 3]
        self.view = self.bc.computeViewMatrix(eye.tolist(), (eye + t[:3, 2]).tolist(), (-t[:3, 1]).tolist())
        self.fy = float(intrinsics[1, 1])

    def image(self, res):
        h, w = res  # the resolution of the umpnet observation the camera was taken from
        fov = math.degrees(2 * math.atan(h / 2 / self.fy))
        proj = self.bc.computeProjectionMatrixFOV(fov, w / h, 0.01, 10.0)
        out = self.bc.getCameraImage(w, h, self.view, proj, renderer=self.renderer)
        return np.reshape(out[2], (h, w, 4)), np.reshape(out[3], (h, w)), np.reshape(out[4], (h, w))

    def close(self):
        self.bc.disconnect()


def umpnet_env(urdf, res, renderer, seed=0):
    env = umpnet.Env(object_dir=urdf, resolution=res, renderer=renderer, seed=seed)
    env.reset()
    return env


def physics(case, repeats):
    """(PyBullet ms, umpnet ms) per action: four pulls open, four pushes back, repeated."""
    from differential import _tangent

    place = {"position": case.position, "orientation": case.orientation, "scale": case.scale}
    art = umpnet.Articulation(case.urdf, physics="reference", **place)
    ref = ReferenceSim(case.urdf, **place)
    art.grasp(case.point, case.link)
    ref.grasp(case.point, case.link)
    times = {"pybullet": [], "umpnet": [], "umpnet_rust": []}
    try:
        for k in range(8 * repeats):
            d = [float(v) for v in _tangent(art, case.joint, 1.0 if (k // 4) % 2 == 0 else -1.0)]
            t = time.perf_counter()
            ref.move(d, case.joint)
            times["pybullet"].append(1e3 * (time.perf_counter() - t))
            t = time.perf_counter()
            out = art.move_gripper(d, case.joint)
            times["umpnet"].append(1e3 * (time.perf_counter() - t))
            times["umpnet_rust"].append(1e3 * out["seconds"])
    finally:
        ref.close()
    return {k: stats(v) for k, v in times.items()}


def observations(urdf, repeats):
    out = {}
    for res in (HI, LO):
        env = umpnet_env(urdf, res, "wgpu")
        obs = env.observe()
        scene = env.scene
        cams = {
            egl: PyBulletCamera(urdf, scene, obs["world_from_camera"], obs["intrinsics"], egl) for egl in (False, True)
        }
        times = {"pybullet_cpu": [], "pybullet_egl": [], "umpnet_python": []}
        for cam in cams.values():
            cam.image(res)  # warm-up
        for r in range(repeats):
            for key, egl in (("pybullet_cpu", False), ("pybullet_egl", True)):
                if key == "pybullet_cpu" and r >= max(3, repeats // 3):
                    continue  # the CPU renderer is slow and steady: fewer samples
                t = time.perf_counter()
                cams[egl].image(res)
                times[key].append(1e3 * (time.perf_counter() - t))
            t = time.perf_counter()
            env.observe()
            times["umpnet_python"].append(1e3 * (time.perf_counter() - t))
        for cam in cams.values():
            cam.close()
        out[f"{res[0]}x{res[1]}"] = {k: stats(v) for k, v in times.items()}
    return out


def episodes(case, urdf, repeats):
    """A grasp and ten pulls along -y, each followed by a 480x640 observation."""
    pull = [0.0, -1.0, 0.0]
    times = {"pybullet_cpu": [], "pybullet_egl": [], "umpnet_python": []}
    env = umpnet_env(urdf, HI, "wgpu")
    scene = env.scene
    obs = env.observe()
    for r in range(repeats):
        for key, egl in (("pybullet_cpu", False), ("pybullet_egl", True)):
            if key == "pybullet_cpu" and r >= max(2, repeats // 5):
                continue
            place = {"position": case.position, "orientation": case.orientation, "scale": case.scale}
            ref = ReferenceSim(case.urdf, **place)
            cam = PyBulletCamera(urdf, scene, obs["world_from_camera"], obs["intrinsics"], egl)
            t = time.perf_counter()
            ref.grasp(case.point, case.link)
            cam.image(HI)
            for _ in range(10):
                ref.move(pull, case.joint)
                cam.image(HI)
            times[key].append(1e3 * (time.perf_counter() - t))
            cam.close()
            ref.close()
        env.reset()
        row, col = env.scripted_action("oracle")
        t = time.perf_counter()
        env.step_position(row, col)
        for _ in range(10):
            env.step_direction(pull)
        times["umpnet_python"].append(1e3 * (time.perf_counter() - t))
    return {k: stats(v) for k, v in times.items()}


def vecenv_rates(sizes, res=LO, steps=30, rounds=3):
    """Direction actions per second of VecEnv (each with an observation), wgpu:
    batched rendering (the default) and each environment drawing its own
    frame, taking turns round by round; the median round of each."""
    rates = {True: {n: [] for n in sizes}, False: {n: [] for n in sizes}}
    envs = {}
    for n in sizes:
        for batch in (True, False):
            env = umpnet.VecEnv(n, seed=0, resolution=res, renderer="wgpu", batch_render=batch)
            env.reset()
            env.step_position(np.array(env.scripted_actions("oracle"), dtype=np.int64))
            envs[n, batch] = env
    rng = np.random.default_rng(0)
    for _ in range(rounds):
        for n in sizes:
            d = rng.normal(size=(steps + 1, n, 3)).astype(np.float32)
            d /= np.linalg.norm(d, axis=2, keepdims=True)
            for batch in (True, False):
                env = envs[n, batch]
                env.step_direction(d[0])  # warm-up
                t = time.perf_counter()
                for k in range(1, steps + 1):
                    env.step_direction(d[k])
                rates[batch][n].append(n * steps / (time.perf_counter() - t))
    med = lambda v: float(np.median(v))
    return {n: med(v) for n, v in rates[True].items()}, {n: med(v) for n, v in rates[False].items()}


def agreement(urdf, seeds=3):
    """Share of object pixels (either renderer) where wgpu and the CPU renderer give the same label."""
    shares = []
    for seed in range(seeds):
        a = umpnet_env(urdf, HI, "wgpu", seed).observe()["segmentation"]
        b = umpnet_env(urdf, HI, "cpu", seed).observe()["segmentation"]
        mask = (a >= OBJECT_SEGMENT) | (b >= OBJECT_SEGMENT)
        shares.append(float((a[mask] == b[mask]).mean()))
    return min(shares)


def rust_figures(urdf, frames):
    umpnet_bin = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
    p = subprocess.run(
        [umpnet_bin, "--json", "bench", "--object", urdf, "--frames", str(frames), "--actions", "100"],
        capture_output=True,
        text=True,
        check=True,
    )
    rows = json.loads(p.stdout)
    out = {}
    for r in rows:
        if r["figure"].startswith("observation") and r["renderer"].startswith("wgpu"):
            out[r["figure"].split()[1]] = r["median_ms"]
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=15)
    p.add_argument("--sizes", default="1,2,4,8", help="VecEnv sizes")
    p.add_argument("--json", action="store_true")
    p.add_argument("--check", action="store_true", help="exit 1 when a target is missed (default: report only)")
    a = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="umpnet-compare-") as folder:
        return compare(Path(folder), a)


def compare(folder: Path, a: argparse.Namespace) -> int:
    case = cabinet_cases(folder)[1]  # the door, pulled along its opening tangent
    urdf = case.urdf
    log = (lambda *_: None) if a.json else (lambda *m: print(*m, file=sys.stderr, flush=True))
    log(f"comparing on {urdf} ({case.name}); {a.repeats} repeats")
    result = {"urdf": CABINET_URDF, "case": case.name}
    with StdoutToStderr():
        log("physics ...")
        result["physics_ms"] = physics(case, a.repeats)
        log("observations ...")
        result["observation_ms"] = observations(urdf, a.repeats)
        log("episodes ...")
        result["episode_480x640_ms"] = episodes(case, urdf, max(3, a.repeats // 3))
        log("umpnet bench (Rust) ...")
        result["rust_ms"] = rust_figures(urdf, a.repeats)
        log("VecEnv ...")
        batched, one_by_one = vecenv_rates([int(n) for n in a.sizes.split(",")])
        result["vecenv_actions_per_s"] = batched
        result["vecenv_one_by_one_actions_per_s"] = one_by_one
        log("render agreement ...")
        result["segmentation_agreement"] = agreement(urdf)
    result["targets"] = targets(result)
    if a.json:
        print(json.dumps(result, indent=1))
    else:
        print(report(result))
    return 1 if a.check and not all(t["met"] for t in result["targets"]) else 0


def targets(r):
    med = lambda d: d["median"]
    obs = r["observation_ms"]["480x640"]
    ep = r["episode_480x640_ms"]
    v = r["vecenv_actions_per_s"]
    rows = [
        (
            "480x640 observation, Python vs PyBullet EGL",
            med(obs["pybullet_egl"]) / med(obs["umpnet_python"]),
            ">=",
            5.0,
        ),
        ("480x640 observation, Python / Rust", med(obs["umpnet_python"]) / r["rust_ms"]["480x640"], "<=", 1.3),
        ("10-action episode, Python vs PyBullet EGL", med(ep["pybullet_egl"]) / med(ep["umpnet_python"]), ">=", 8.0),
        (
            "physics per action vs PyBullet",
            med(r["physics_ms"]["pybullet"]) / med(r["physics_ms"]["umpnet"]),
            ">=",
            100.0,
        ),
    ]
    if 1 in v and 2 in v:
        rows.append(("VecEnv 120x160, n=2 / n=1", v[2] / v[1], ">=", 1.8))
    if 2 in v and 8 in v:
        rows.append(("VecEnv 120x160, n=8 / n=2", v[8] / v[2], ">=", 1.0))
    rows.append(("segmentation agreement, wgpu vs CPU", r["segmentation_agreement"], ">=", 0.99))
    return [
        {"figure": f, "value": x, "target": f"{op} {t}", "met": bool(x >= t if op == ">=" else x <= t)}
        for f, x, op, t in rows
    ]


def report(r):
    def cell(d):
        return f"{d['min']:.2f} / {d['median']:.2f}" if d else "-"

    lines = ["wall ms, min / median", ""]
    head = f"{'figure':<30} {'PyBullet CPU':>17} {'PyBullet EGL':>17} {'umpnet Python':>17} {'umpnet Rust':>12}"
    lines += [head, "-" * len(head)]
    ph = r["physics_ms"]
    lines.append(
        f"{'physics per 0.18 m action':<30} {cell(ph['pybullet']):>17} {'same':>17} "
        f"{cell(ph['umpnet']):>17} {ph['umpnet_rust']['median']:>12.3f}"
    )
    for res, o in r["observation_ms"].items():
        lines.append(
            f"{res + ' observation':<30} {cell(o['pybullet_cpu']):>17} {cell(o['pybullet_egl']):>17} "
            f"{cell(o['umpnet_python']):>17} {r['rust_ms'].get(res, float('nan')):>12.2f}"
        )
    ep = r["episode_480x640_ms"]
    lines.append(
        f"{'10-action episode, 480x640':<30} {cell(ep['pybullet_cpu']):>17} {cell(ep['pybullet_egl']):>17} "
        f"{cell(ep['umpnet_python']):>17} {'-':>12}"
    )
    lines += [
        "",
        "VecEnv at 120x160 (wgpu), batched: "
        + ", ".join(f"n={n}: {v:.0f}/s" for n, v in r["vecenv_actions_per_s"].items()),
        "VecEnv at 120x160 (wgpu), one by one: "
        + ", ".join(f"n={n}: {v:.0f}/s" for n, v in r["vecenv_one_by_one_actions_per_s"].items()),
    ]
    lines += [f"segmentation agreement, wgpu vs CPU renderer: {r['segmentation_agreement']:.4f}", "", "targets:"]
    for t in r["targets"]:
        lines.append(
            f"  {'met ' if t['met'] else 'MISS'}  {t['figure']:<44} {t['value']:>9.2f}  (target {t['target']})"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
