"""Bad input through the Python bindings: a Python exception naming what was
wrong and what was expected, never a crash."""

import os
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import umpnet

RES = (48, 64)


def test_errors_are_python_exceptions():
    env = umpnet.Env(category=["Door"], seed=0, resolution=RES)
    env.reset()
    with pytest.raises(ValueError, match="before a position action"):
        env.step_direction([1.0, 0.0, 0.0])
    env.step_position(*env.scripted_action("oracle"))
    with pytest.raises(ValueError, match="finite and non-zero"):
        env.step_direction([float("nan"), 0.0, 0.0])
    with pytest.raises(ValueError, match="3 components"):
        env.step_direction([1.0, 0.0])
    with pytest.raises(ValueError, match="already taken"):
        env.step_position(1, 1)
    with pytest.raises(ValueError, match="unknown category"):
        umpnet.Env(category=["Spaceship"])
    with pytest.raises(ValueError, match="split"):
        umpnet.Env(split="validation")
    with pytest.raises(ValueError, match="outside the 48x64 image"):
        e2 = umpnet.Env(seed=1, resolution=RES)
        e2.reset()
        e2.step_position(100, 5)
    # Indices are checked, not cast: 2**32 + 5 must not wrap round to pixel 5.
    with pytest.raises(ValueError, match="inside the image"):
        e2.step_position(2**32 + 5, 5)
    vec = umpnet.VecEnv(2, resolution=RES)
    vec.reset()
    with pytest.raises(ValueError, match="inside the image"):
        vec.step_position(np.array([[2**32 + 5, 5], [1, 1]], np.int64))
    vec = umpnet.VecEnv(2, resolution=RES)
    vec.reset()
    with pytest.raises(ValueError, match=r"expected \(2, 2\)"):
        vec.step_position(np.zeros((3, 2), dtype=np.int64))
    with pytest.raises(ValueError, match="scene JSON"):
        env.reset(scene="{not json")
    with pytest.raises(ValueError, match="model.json"):
        umpnet.Policy("/nonexistent")


def test_articulation_reports_bad_input_by_name(tmp_path):
    umpnet_bin = os.environ.get("UMPNET_BIN", "target/release/umpnet")
    subprocess.run(
        [umpnet_bin, "objects", "generate", "--out", str(tmp_path), "--per-category", "1", "--categories", "Microwave"],
        check=True,
        capture_output=True,
    )
    urdf = str(tmp_path / "Microwave" / "0" / "mobility.urdf")
    art = umpnet.Articulation(urdf, scale=0.55)
    joint = art.joint_names()[0]
    link, _, _ = art.joint_axis(joint)
    with pytest.raises(RuntimeError, match="grasp"):
        art.move_gripper([0, -1, 0], joint)
    with pytest.raises(ValueError, match="no link named"):
        art.grasp([0, 0, 0], "nope")
    with pytest.raises(ValueError, match="direction"):
        art.grasp(list(np.mean(art.link_vertices(link), axis=0)), link)
        art.move_gripper([0, 0, 0], joint)
    with pytest.raises(ValueError, match="steps_per_update"):
        umpnet.Articulation(urdf, steps_per_update=0)
    # A real move reports the time its physics took inside Rust: positive, and
    # below the wall time of the whole Python call.
    t = time.perf_counter()
    out = art.move_gripper([0, -1, 0], joint)
    wall = time.perf_counter() - t
    assert out["steps"] > 0 and 0 < out["seconds"] <= wall
    with pytest.raises(ValueError, match="scale"):
        umpnet.Articulation(urdf, scale=-1.0)
    # Usable from another thread (a worker pool, a GUI): no "unsendable" panic.
    import concurrent.futures

    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        names = pool.submit(art.joint_names).result()
        moved = pool.submit(art.move_gripper, [0, -1, 0], joint).result()
    assert names == art.joint_names() and moved["steps"] > 0


def test_absurd_sizes_are_value_errors_not_crashes():
    with pytest.raises(ValueError, match="expected 1 to 4096 environments"):
        umpnet.VecEnv(2**62)
    with pytest.raises(ValueError, match="n = 0"):
        umpnet.VecEnv(0)
    with pytest.raises(ValueError, match="threads = 100000"):
        umpnet.Policy(str(Path(__file__).resolve().parents[3] / "models" / "umpnet-small"), threads=100000)
    # Negative sizes name the argument; they used to be a bare OverflowError.
    with pytest.raises(ValueError, match=r"resolution \(-96, 128\): expected \(height, width\)"):
        umpnet.Env(resolution=(-96, 128))
    with pytest.raises(ValueError, match="n = -1"):
        umpnet.VecEnv(-1)


def test_magnitudes_that_mean_nothing_are_refused_by_name():
    cabinet = str(Path(__file__).resolve().parents[3] / "crates" / "sim" / "tests" / "data" / "cabinet.urdf")
    art = umpnet.Articulation(cabinet, position=(0.0, -0.5, 0.0))
    # A joint value past its limit was clamped without a word.
    with pytest.raises(
        ValueError,
        match=r"joint `drawer_slide` = 1000000000000000000000000000000 is outside its limits \[0, 0.4\] \(m\)",
    ):
        art.set_joints({"drawer_slide": 1e30})
    art.set_joints({"drawer_slide": 0.2})
    assert art.joint("drawer_slide") == pytest.approx(0.2)
    # A grasp 1e30 m from the part used to succeed.
    with pytest.raises(ValueError, match=r"m from the link's geometry; suction holds a surface within 0.05 m"):
        art.grasp([0.0, 1e30, 0.25], "drawer")
    art.set_joints({"drawer_slide": 0.0})
    art.grasp([0.0, -0.76, 0.25], "drawer")
    assert art.move_gripper([0.0, -1.0, 0.0], "drawer_slide")["joint_after"] > 0.1


def test_direction_batch_refuses_pixels_outside_the_image():
    pol = umpnet.Policy(str(Path(__file__).resolve().parents[3] / "models" / "umpnet-small"))
    h, w = pol.resolution
    images = np.zeros((1, h, w, 10), np.float32)
    images[..., 9] = 1.0
    for bad in [(-5, 10), (10, 10**6), (h, 0)]:
        with pytest.raises(ValueError, match=rf"pixels\[0\] = \({bad[0]}, {bad[1]}\) is outside the {h} x {w} image"):
            pol.direction_batch(images, images.copy(), np.array([bad], np.int64))
    assert len(pol.direction_batch(images, images.copy(), np.array([[h - 1, w - 1]], np.int64))) == 1


def test_policy_position_rejects_a_goal_of_another_shape():
    pol = umpnet.Policy(str(Path(__file__).resolve().parents[3] / "models" / "umpnet-small"))
    h, w = pol.resolution
    image = np.zeros((h, w, 10), np.float32)
    image[..., 9] = 1.0
    with pytest.raises(ValueError, match="goal observation has shape"):
        pol.position(image, np.zeros((h // 2, w, 10), np.float32))
    assert len(pol.position(image, image.copy())) == 2


def test_wrong_array_dtypes_name_what_was_expected():
    pol = umpnet.Policy(str(Path(__file__).resolve().parents[3] / "models" / "umpnet-small"))
    h, w = pol.resolution
    with pytest.raises(TypeError, match=r"argument 'image'.*float32 array with 3 dimensions.*got a float64 array"):
        pol.position(np.zeros((h, w, 10)), None)
    with pytest.raises(TypeError, match=r"float32 array with 3 dimensions.*got a float32 array of shape \[4, 4\]"):
        pol.position(np.zeros((4, 4), np.float32), None)
    envs = umpnet.VecEnv(2, resolution=RES)
    envs.reset()
    with pytest.raises(TypeError, match=r"argument 'pixels'.*int64 array with 2 dimensions.*got a list"):
        envs.step_position([[1, 2], [3, 4]])
