"""The Python bindings' `Env`: shapes and dtypes, same seed same episode,
physics profiles, training labels and dense fields, probes, and one config
for every way to build an environment."""

import json
import os
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import umpnet

RES = (48, 64)


def episode(env, steps=3, policy="oracle"):
    obs = env.reset()
    px = env.scripted_action(policy)
    obs, info = env.step_position(*px)
    out = [obs["image"].copy()]  # the env's buffers are rewritten by the next step
    labels = []
    for _ in range(steps):
        if not info["valid"]:
            break
        d = env.scripted_action(policy)
        if d is None:
            break
        obs, lab, _ = env.step_direction(d)
        out.append(obs["image"].copy())
        labels.append((lab["r_dist"], lab["aot"], lab["moved"]))
    return out, labels


def test_reset_and_step_shapes_and_dtypes():
    env = umpnet.Env(category=["Microwave"], seed=3, resolution=RES)
    obs = env.reset()
    assert obs["image"].shape == (48, 64, 10) and obs["image"].dtype == np.float32
    assert obs["reference"].shape == (48, 64, 10)
    assert obs["segmentation"].shape == (48, 64)
    assert obs["intrinsics"].shape == (3, 3) and obs["world_from_camera"].shape == (4, 4)
    assert tuple(obs["gripper_pixel"]) == (-1, -1)
    row, col = env.scripted_action("oracle")
    obs, info = env.step_position(row, col)
    assert info["valid"] and info["joint"] is not None and len(info["point_in_world"]) == 3
    assert (obs["gripper_pixel"] >= 0).all()
    obs, labels, info = env.step_direction(env.scripted_action("oracle"))
    assert set(labels) == {"r_dist", "aot", "moved", "train_aot", "train_moved"} and labels["aot"] in (-1, 0, 1)
    assert isinstance(info["joints"], list) and "reached_limit" in info


def test_same_seed_same_episode_and_scene_replay():
    a, la = episode(umpnet.Env(category=["Door", "Laptop"], seed=11, resolution=RES), policy="random")
    b, lb = episode(umpnet.Env(category=["Door", "Laptop"], seed=11, resolution=RES), policy="random")
    assert la == lb and all(np.array_equal(x, y) for x, y in zip(a, b))
    env = umpnet.Env(seed=5, resolution=RES)
    first = env.reset()["image"].copy()
    scene = env.scene
    assert isinstance(scene, dict) and scene["task"] == "exploration"
    assert not np.array_equal(env.reset()["image"], first)  # another scene
    assert np.array_equal(env.reset(scene=scene)["image"], first)
    assert np.array_equal(env.reset(scene=json.dumps(scene))["image"], first)  # JSON text too
    with pytest.raises(TypeError, match="scene must be a dict"):
        env.reset(scene=3)


def test_physics_profile_reaches_the_scene_and_changes_what_a_pull_does():
    moved = {}
    for physics in ["reference", "ideal"]:
        env = umpnet.Env(category=["StorageFurniture"], seed=3, resolution=RES, physics=physics)
        env.reset()
        assert env.scene["physics"] == physics
        _, labels = episode(env, steps=2)
        moved[physics] = [r for r, _, _ in labels]
    assert moved["reference"] != moved["ideal"]
    # What the profile changes: on a free drawer pulled straight out, the
    # reference (PyBullet's mount) moves it 0.13 m per 0.18 m action, the
    # ideal profile the full 0.18 m; both stop at its 0.4 m limit.
    cabinet = str(Path(__file__).resolve().parents[3] / "crates" / "sim" / "tests" / "data" / "cabinet.urdf")
    for physics, per_action in [("reference", 0.130), ("ideal", 0.18)]:
        art = umpnet.Articulation(cabinet, physics=physics, position=(0.0, -0.5, 0.0))
        art.grasp([0.0, -0.76, 0.25], "drawer")
        after = [art.move_gripper([0.0, -1.0, 0.0], "drawer_slide")["joint_after"] for _ in range(4)]
        np.testing.assert_allclose(after[0], per_action, atol=0.003, err_msg=physics)
        np.testing.assert_allclose(after[1], 2 * per_action, atol=0.006, err_msg=physics)
        np.testing.assert_allclose(after[3], 0.4, atol=0.002, err_msg=physics)
    with pytest.raises(ValueError, match="reference or ideal"):
        umpnet.Env(physics="bullet")


def test_torch_optimizer_after_rendering_in_the_same_process():
    """umpnet_train loads torch's lazy native parts before any environment renders
    (Mesa's LLVM then torch's segfaulted); check it in a fresh process."""
    import sys
    from pathlib import Path

    code = (
        "import umpnet_train, torch, umpnet\n"
        "e = umpnet.Env(seed=1, resolution=(48, 64)); e.reset()\n"
        "torch.optim.Adam([torch.zeros(1, requires_grad=True)])\n"
        "print('ok')\n"
    )
    root = Path(__file__).resolve().parents[3]
    env = {**os.environ, "PYTHONPATH": str(root / "train_py")}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False)
    assert res.returncode == 0 and "ok" in res.stdout, res.stderr[-2000:]


def test_probe_directions_gives_dense_labels_without_changing_the_episode():
    vec = umpnet.VecEnv(3, category=["Microwave", "StorageFurniture"], resolution=RES, seed=5)
    vec.reset()
    vec.step_position(np.array(vec.scripted_actions("oracle")))
    dirs = np.random.default_rng(0).normal(size=(3, 16, 3)).astype(np.float32)
    dirs[:, 0] = np.array(vec.scripted_actions("oracle"), dtype=np.float32)
    first = vec.probe_directions(dirs)
    again = vec.probe_directions(dirs)
    for key in ["r_dist", "aot", "moved", "joint_after"]:
        assert first[key].shape == (3, 16)
        np.testing.assert_array_equal(first[key], again[key])
    # The oracle's own direction moves the part. Probing it predicts the step
    # exactly, which also shows the probes left the state as it was.
    assert (first["r_dist"][:, 0] > 0.05).all(), first["r_dist"][:, 0]
    _, labels, info = vec.step_direction(dirs[:, 0])
    np.testing.assert_array_equal(labels["r_dist"], first["r_dist"][:, 0])
    np.testing.assert_array_equal(labels["train_aot"], first["train_aot"][:, 0])
    assert info["reached_boundary"].dtype == bool and info["reached_init"].dtype == bool
    with pytest.raises(ValueError, match=r"expected \(3, K, 3\)"):
        vec.probe_directions(np.zeros((2, 4, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="non-zero"):
        vec.probe_directions(np.zeros((3, 4, 3), dtype=np.float32))
    # An unbounded K would run for minutes with no way to stop it: refused up front.
    many = np.ones((3, 1025, 3), dtype=np.float32)
    with pytest.raises(ValueError, match="at most 1024 per call"):
        vec.probe_directions(many)


def test_a_long_probe_stops_on_ctrl_c():
    import _thread
    import signal
    import threading

    vec = umpnet.VecEnv(1, category=["StorageFurniture"], resolution=RES, seed=5)
    vec.reset()
    vec.step_position(np.array(vec.scripted_actions("oracle")))
    dirs = np.random.default_rng(0).normal(size=(1, 1024, 3)).astype(np.float32)
    t = time.perf_counter()
    full = vec.probe_directions(dirs)
    whole = time.perf_counter() - t
    # The probe answers in chunks, so the labels are those of one call.
    np.testing.assert_array_equal(full["r_dist"][:, :32], vec.probe_directions(dirs[:, :32])["r_dist"])
    # A process started in the background by a shell without job control
    # inherits SIGINT ignored, and then interrupt_main does nothing: Ctrl-C's
    # default handler is set here, so the test checks the probe, not the shell.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(whole / 10, _thread.interrupt_main)
    try:
        timer.start()
        t = time.perf_counter()
        with pytest.raises(KeyboardInterrupt):
            vec.probe_directions(dirs)
        stopped = time.perf_counter() - t
        timer.join()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert stopped < whole / 2, (stopped, whole)


def test_training_labels_use_the_reference_thresholds():
    vec = umpnet.VecEnv(4, category=["StorageFurniture", "Microwave"], resolution=RES, seed=9)
    vec.reset()
    _, pos = vec.step_position(np.array(vec.scripted_actions("oracle")))
    assert pos["limits"].shape == (4, 2) and pos["threshold"].shape == (4,)
    dirs = np.random.default_rng(1).normal(size=(4, 32, 3)).astype(np.float32)
    probe = vec.probe_directions(dirs)
    # moved <=> |dj| > 0.1 rad / 0.05 m or > range/3.5, i.e. above the threshold;
    # from the start every move counts as forward.
    thr = pos["threshold"][:, None]
    np.testing.assert_array_equal(probe["train_moved"], probe["r_dist"] > thr)
    np.testing.assert_array_equal(probe["train_aot"], probe["train_moved"].astype(np.int64))
    # Between the threshold and delta the paper's text says "no change": the
    # training labels are what the released code trains on.
    between = (probe["r_dist"] > thr) & (probe["r_dist"] <= 0.15)
    assert between.any(), probe["r_dist"]
    assert (probe["aot"][between] == 0).all() and (probe["train_aot"][between] == 1).all()


@pytest.mark.parametrize(("category", "seed"), [("Microwave", 3), ("StorageFurniture", 1), ("Laptop", 2)])
def test_articulation_flow_points_the_way_a_pull_opens_the_part(category, seed):
    env = umpnet.Env(category, seed=seed, resolution=RES, task="exploration")
    obs = env.reset()
    f = env.articulation_fields()
    assert f["goal_displacement"] is None
    norms = np.linalg.norm(f["flow"], axis=-1)
    assert f["movable"].sum() > 20 and (~f["movable"] & (obs["segmentation"] > 0)).sum() > 0
    assert np.all(norms[~f["movable"]] == 0)
    on = norms[f["movable"]]
    assert np.all((np.abs(on - 1) < 1e-4) | (on == 0))
    assert np.all((f["joint"] >= 0) == f["movable"])
    row, col = env.scripted_action("oracle")
    _, info = env.step_position(row, col)
    assert info["valid"] and info["joint"] == f["joint"][row, col]
    # Along the flow the part opens (the joint grows); against it, it closes
    # (the training labels' thresholds: 0.1 rad / 0.05 m).
    flow = [float(v) for v in f["flow"][row, col]]
    _, opened, _ = env.step_direction(flow)
    _, closed, _ = env.step_direction([-v for v in flow])
    assert opened["r_dist"] > 0.05 and opened["train_aot"] == 1, opened
    assert closed["r_dist"] > 0.05 and closed["train_aot"] == -1, closed


def test_goal_displacement_moves_only_the_goal_part_and_stacks_in_vecenv():
    env = umpnet.Env("Door", seed=1, resolution=RES, task="goal")
    env.reset()
    f = env.articulation_fields()
    goal_joint = env.scene["goal"]["joint"]
    moving = np.linalg.norm(f["goal_displacement"], axis=-1) > 1e-4
    assert moving.sum() > 20
    assert np.all(f["joint"][moving] == goal_joint)
    vec = umpnet.VecEnv(2, resolution=RES, task="goal", seed=1)
    vec.reset()
    stacked = vec.articulation_fields()
    assert stacked["flow"].shape == (2, *RES, 3) and stacked["goal_displacement"].shape == (2, *RES, 3)
    assert stacked["movable"].dtype == bool and stacked["joint"].dtype == np.int32


def test_one_env_config_serves_env_and_vec_env_and_places_object_files():
    """EnvConfig declares the scene settings once: Env(config=c) and
    VecEnv(n, config=c) are Env(**options) and VecEnv(n, **options); scale
    and pose place an object file over its object_meta_info.json."""
    cabinet = str(Path(__file__).resolve().parents[3] / "crates" / "sim" / "tests" / "data" / "cabinet.urdf")
    options = {"split": "test", "resolution": (48, 64), "task": "goal", "renderer": "cpu"}
    config = umpnet.EnvConfig("Door", **options)
    assert "Door" in repr(config) and "goal" in repr(config)
    a = umpnet.Env(config=config, seed=4, copy=True).reset()
    b = umpnet.Env("Door", seed=4, copy=True, **options).reset()
    assert np.array_equal(a["image"], b["image"]) and np.array_equal(a["reference"], b["reference"])
    v = umpnet.VecEnv(2, config=config, seed=4, copy=True).reset()
    assert np.array_equal(v["image"][0], a["image"])
    with pytest.raises(ValueError, match="not both"):
        umpnet.Env(config=config, split="train")
    with pytest.raises(TypeError, match="splt"):
        umpnet.Env("Door", splt="test")
    with pytest.raises(ValueError, match="object_dir"):
        umpnet.EnvConfig(scale=0.5)

    def object_pixels(**placement):
        env = umpnet.Env(object_dir=cabinet, seed=1, resolution=(96, 128), renderer="cpu", copy=True, **placement)
        obs = env.reset()
        return int((obs["segmentation"] > 1).sum()), env.scene

    full, scene = object_pixels()
    half, half_scene = object_pixels(scale=0.5)
    assert half_scene["object"]["pose"]["scale"] == 0.5 and "pose" not in scene["object"]
    assert 0.1 * full < half < 0.5 * full, (full, half)  # a quarter of the area, give or take perspective
    lying, lying_scene = object_pixels(pose=(0.7071068, 0, 0, 0.7071068, 0.0))
    assert lying_scene["object"]["pose"]["orientation"] == pytest.approx([0.7071068, 0, 0, 0.7071068])
    assert lying != full
    with pytest.raises(ValueError, match="unit quaternion"):
        umpnet.Env(object_dir=cabinet, pose=(1, 1, 0, 0))
    with pytest.raises(ValueError, match="4 numbers|qx, qy, qz, qw"):
        umpnet.Env(object_dir=cabinet, pose=(1, 0))
    with pytest.raises(ValueError, match="scale"):
        umpnet.Env(object_dir=cabinet, scale=-1.0)


def test_glass_depth_through_reads_behind_a_glass_door_and_keeps_its_colour(tmp_path):
    """A camera with glass_depth="through" sees depth and segments behind a
    glass door (as an active depth camera reads clear glass), one with
    "missing" nothing there; the colour image is the default's, which shows
    the pane."""
    source = Path(__file__).resolve().parents[3] / "crates" / "sim" / "tests" / "data" / "cabinet.urdf"
    door = '<visual><origin xyz="0.4 -0.01 0"/><geometry><box size="0.8 0.02 0.45"/></geometry>'
    text = source.read_text()
    assert door in text
    glazed = tmp_path / "cabinet.urdf"
    glazed.write_text(text.replace(door, door + '<material name="glass"><color rgba="0.6 0.8 0.9 0.3"/></material>'))
    door_segment = (1 << 16) + 1

    def observe(glass_depth):
        config = umpnet.EnvConfig(object_dir=str(glazed), resolution=RES, renderer="cpu", glass_depth=glass_depth)
        assert f'glass_depth="{glass_depth}"' in repr(config)
        return umpnet.Env(config=config, seed=1, copy=True).reset()

    surface, through, missing = observe("surface"), observe("through"), observe("missing")
    rgb = slice(3, 6)  # the image's channels: xyz, rgb, normal, depth
    assert np.array_equal(surface["image"][..., rgb], through["image"][..., rgb])
    assert np.array_equal(surface["image"][..., rgb], missing["image"][..., rgb])
    seen = surface["segmentation"] == door_segment
    assert seen.sum() > 20, seen.sum()
    assert not (through["segmentation"] == door_segment).any()
    # Behind the door is the cabinet's body, farther from the camera.
    depth_surface, depth_through = surface["image"][..., 9][seen], through["image"][..., 9][seen]
    assert (depth_through > depth_surface).mean() > 0.9
    # A camera that reads nothing on glass sees nothing where the door is.
    assert (missing["segmentation"][seen] == 0).all() and (missing["image"][..., 9][seen] == 0).all()
    assert np.array_equal(missing["image"][..., 9][~seen], surface["image"][..., 9][~seen])
    assert np.array_equal(missing["segmentation"][~seen], surface["segmentation"][~seen])
    with pytest.raises(ValueError, match="glass depth `clear`"):
        umpnet.EnvConfig(glass_depth="clear")
    # A VecEnv's environments may each read glass their own way.
    config = umpnet.EnvConfig(object_dir=str(glazed), resolution=RES, renderer="cpu")
    mixed = umpnet.VecEnv(3, config=config, seed=1, copy=True, glass_depths=["surface", "through", "missing"]).reset()
    plain = umpnet.VecEnv(3, config=config, seed=1, copy=True).reset()
    for i, expect_door in enumerate([True, False, False]):
        assert (mixed["segmentation"][i] == door_segment).any() == expect_door, i
    assert np.array_equal(mixed["image"][0], plain["image"][0])
    assert np.array_equal(mixed["image"][1][..., rgb], plain["image"][1][..., rgb])
    with pytest.raises(ValueError, match="2 readings for 3 environments"):
        umpnet.VecEnv(3, config=config, glass_depths=["surface", "through"])
    with pytest.raises(ValueError, match="glass_depths: unknown glass depth `opaque`"):
        umpnet.VecEnv(1, config=config, glass_depths=["opaque"])
