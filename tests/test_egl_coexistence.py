"""umpnet's wgpu renderer and PyBullet's EGL renderer in one process.

wgpu used to enable its GL backend beside Vulkan, which initialises EGL in
the process; PyBullet's EGL renderer beside it then returned stale frames.
umpnet now asks for Vulkan only (GL is opt-in through WGPU_BACKEND). Each
renderer is compared with its own CPU renderer, frame by frame, while the
camera moves: a stale frame disagrees.
"""

import os
import pkgutil

import numpy as np
import pybullet as pb
import pybullet_data
import pytest
import umpnet

RES = (120, 160)


def object_agreement(a, b, background):
    """Share of pixels that either renderer sees as object where both give the same label."""
    mask = (a != background) | (b != background)
    return float((a[mask] == b[mask]).mean()) if mask.any() else 1.0


def umpnet_agreement(seed):
    gpu = umpnet.Env(seed=seed, resolution=RES, renderer="wgpu").reset()["segmentation"]
    cpu = umpnet.Env(seed=seed, resolution=RES, renderer="cpu").reset()["segmentation"]
    return object_agreement(gpu, cpu, background=0)


def pybullet_frames(client, n):
    """(EGL, TinyRenderer) segmentation pairs from n camera positions around the scene."""
    frames = []
    proj = pb.computeProjectionMatrixFOV(60, RES[1] / RES[0], 0.1, 10, physicsClientId=client)
    for k in range(n):
        angle = 2 * np.pi * k / n
        eye = [2.0 * np.cos(angle), 2.0 * np.sin(angle), 1.2]
        view = pb.computeViewMatrix(eye, [0, 0, 0.4], [0, 0, 1], physicsClientId=client)
        pair = []
        for renderer in (pb.ER_BULLET_HARDWARE_OPENGL, pb.ER_TINY_RENDERER):
            img = pb.getCameraImage(RES[1], RES[0], view, proj, renderer=renderer, physicsClientId=client)
            pair.append(np.reshape(img[4], RES))
        frames.append(pair)
    return frames


def test_wgpu_and_pybullet_egl_in_one_process_both_agree_with_their_cpu_renderers():
    if "WGPU_BACKEND" in os.environ:
        pytest.fail(f"WGPU_BACKEND={os.environ['WGPU_BACKEND']} overrides the default this test checks")
    before = umpnet_agreement(seed=1)
    client = pb.connect(pb.DIRECT)
    egl = pkgutil.get_loader("eglRenderer")
    assert egl is not None, "pybullet's eglRenderer plugin is missing"
    assert pb.loadPlugin(egl.get_filename(), "_eglRendererPlugin", physicsClientId=client) >= 0
    pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=client)
    for i, (name, pos) in enumerate(
        [("cube.urdf", [0, 0, 0.5]), ("sphere2.urdf", [0.6, 0.3, 0.4]), ("duck_vhacd.urdf", [-0.5, -0.4, 0.2])]
    ):
        pb.loadURDF(name, pos, globalScaling=0.6 if i else 0.8, physicsClientId=client)
    # Interleave: umpnet renders between PyBullet's frames, as a mixed training loop would.
    agreements = []
    for seed in range(3):
        for egl_seg, cpu_seg in pybullet_frames(client, 4):
            agreements.append(object_agreement(egl_seg, cpu_seg, background=-1))
        agreements.append(umpnet_agreement(seed=seed + 2))
    pb.disconnect(client)
    after = umpnet_agreement(seed=1)
    assert before >= 0.99 and after >= 0.99, (before, after)
    assert min(agreements) >= 0.99, [round(a, 3) for a in agreements]
