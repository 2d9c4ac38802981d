"""The Python bindings: shapes, determinism, replay, VecEnv == Envs, gymnasium, errors."""

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


def test_vecenv_equals_separate_envs():
    n = 3
    vec = umpnet.VecEnv(n, seed=20, resolution=RES)
    obs = vec.reset()
    envs = [umpnet.Env(seed=20 + i, resolution=RES) for i in range(n)]
    singles = [e.reset() for e in envs]
    assert obs["image"].shape == (n, 48, 64, 10)
    for i in range(n):
        assert np.array_equal(obs["image"][i], singles[i]["image"])
        assert np.array_equal(obs["reference"][i], singles[i]["reference"])
    pixels = np.array(vec.scripted_actions("oracle"), dtype=np.int64)
    obs, info = vec.step_position(pixels)
    assert info["gripper_in_world"].shape == (n, 3)
    for i, e in enumerate(envs):
        o, inf = e.step_position(*pixels[i])
        assert inf["valid"] == info["valid"][i]
        assert np.array_equal(o["image"], obs["image"][i])
        held = inf["gripper_in_world"]  # None where the grasp missed: NaN in the VecEnv's row
        assert (
            np.isnan(info["gripper_in_world"][i]).all()
            if held is None
            else held == info["gripper_in_world"][i].tolist()
        )
    dirs = np.array([d if d is not None else [0, 0, 1] for d in vec.scripted_actions("oracle")], dtype=np.float32)
    before = info["gripper_in_world"].copy()
    obs, labels, info = vec.step_direction(dirs)
    for i, e in enumerate(envs):
        if not info["active"][i]:
            continue
        o, lab, inf = e.step_direction(dirs[i].tolist())
        assert lab["aot"] == labels["aot"][i] and abs(lab["r_dist"] - labels["r_dist"][i]) < 1e-6
        assert np.array_equal(o["image"], obs["image"][i])
        assert inf["gripper_in_world"] == info["gripper_in_world"][i].tolist()
        # A move goes at most its 0.18 m.
        assert np.linalg.norm(info["gripper_in_world"][i] - before[i]) <= 0.18 + 1e-3


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


def test_gymnasium_check_env():
    import gymnasium as gym  # a requirement (train_py/requirements.txt), never skipped
    import umpnet.gym  # noqa: F401  (registers the ids)
    from gymnasium.utils.env_checker import check_env

    env = gym.make("umpnet/Explore-v0", resolution=RES, category=["Door"]).unwrapped
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert obs["phase"] == 0 and "scene" in info
    obs, _r, _term, _trunc, info = env.step({"phase": 0, "pixel": np.array([24, 32]), "direction": np.zeros(3)})
    assert obs["phase"] == 1


def test_policy_runs_on_env_observations(fixture_package):
    pol = umpnet.Policy(fixture_package)
    h, w = pol.resolution
    env = umpnet.Env(seed=2, resolution=(h, w))
    obs = env.reset()
    row, col = pol.position(obs["image"])
    assert 0 <= row < h and 0 <= col < w
    out = pol.direction_batch(obs["image"][None], obs["reference"][None], np.array([[row, col]]), mode="explore")
    assert len(out) == 1 and len(out[0]["candidates"]) == len(out[0]["distance"]) >= 64
    assert out[0]["direction"] is not None and abs(np.linalg.norm(out[0]["direction"]) - 1) < 1e-4


def test_policy_reads_a_joint_from_one_frame_as_the_runtime_votes_it(fixture_package):
    """Policy.frame_joint runs the package's JointNet and votes over the part
    at the pixel; joint_from_fields gives the same vote from outputs computed
    elsewhere (a training checkpoint); bad input is a ValueError naming it."""
    import onnxruntime as ort

    package = Path(fixture_package) / "joint"
    pol = umpnet.Policy(str(package))
    env = umpnet.Env("Microwave", seed=3, resolution=pol.resolution, copy=True)
    image = env.reset()["image"]
    h, w = pol.resolution
    joint = pol.frame_joint(image, (h // 2, w // 2))
    assert joint["type"] == "prismatic" and joint["axis"] == [1.0, 0.0, 0.0] and joint["point"] is None
    fields = ort.InferenceSession(str(package / "joint.onnx")).run(None, {"observation": image[None]})[0][0]
    assert umpnet._umpnet.joint_from_fields(image, fields, (h // 2, w // 2)) == joint
    # The same outputs saying "static" everywhere: the grasped surface near
    # the grasp votes alone, the same way.
    still = fields.copy()
    still[0] = -5.0
    near = umpnet._umpnet.joint_from_fields(image, still, (h // 2, w // 2))
    assert near["type"] == joint["type"] and 3 <= near["voting_pixels"] < joint["voting_pixels"]
    # Nothing to vote on without depth at the grasp.
    hole = image.copy()
    hole[h // 2, w // 2, 9] = 0.0
    assert umpnet._umpnet.joint_from_fields(hole, fields, (h // 2, w // 2)) is None
    assert umpnet.Policy(str(Path(fixture_package) / "steer")).frame_joint(image, (h // 2, w // 2)) is None
    with pytest.raises(ValueError, match="pixel"):
        pol.frame_joint(image, (h, 0))
    with pytest.raises(ValueError, match=r"expected \(H, W, 10\) and \(11, H, W\)"):
        umpnet._umpnet.joint_from_fields(image, fields[:5], (0, 0))


def test_the_mirror_of_an_observation_is_the_same_scene_seen_in_a_mirror():
    """mirrored_observations (the runtime's mirror, which the fine-tune's
    --mirror also uses) holds for the benchmark camera: it sits in the plane
    x = 0 with its image x along the world's, so a point's x over its depth
    depends only on the column, and is opposite in the mirrored column."""
    obs = umpnet.Env("Door", seed=5, resolution=RES).reset()["image"]
    h, w = obs.shape[:2]
    seen = obs[..., 9] > 0
    both = seen & seen[:, ::-1]
    slope = np.where(seen, obs[..., 0] / np.where(seen, obs[..., 9], 1.0), 0.0)
    assert both.sum() > h * w // 4
    assert np.allclose(slope[both], -slope[:, ::-1][both], atol=1e-4)
    m = umpnet._umpnet.mirrored_observations(obs[None])[0]
    assert m.dtype == np.float32 and m.shape == obs.shape
    assert np.array_equal(m[:, ::-1, [0, 6]], -obs[..., [0, 6]])
    keep = [c for c in range(10) if c not in (0, 6)]
    assert np.array_equal(m[:, ::-1, keep], obs[..., keep])
    assert np.array_equal(umpnet._umpnet.mirrored_observations(m[None])[0], obs)
    with pytest.raises(ValueError, match=r"expected \(N, H, W, 10\)"):
        umpnet._umpnet.mirrored_observations(obs[None, ..., :9].copy())


def panel_image(h, w, x, z):
    """An H x W observation through a pinhole at the origin looking down +z:
    a wall at z = 2 and a 0.4 m panel at depth z centred at (x, 0)."""
    u = (np.arange(w) + 0.5 - w / 2) / w
    v = (np.arange(h) + 0.5 - h / 2) / w
    uu, vv = np.meshgrid(u, v)
    on_panel = (np.abs(uu * z - x) < 0.2) & (np.abs(vv * z) < 0.2)
    depth = np.where(on_panel, z, 2.0).astype(np.float32)
    image = np.zeros((h, w, 10), np.float32)
    image[..., 0], image[..., 1], image[..., 2], image[..., 9] = uu * depth, vv * depth, depth, depth
    return image


def test_the_goal45_filter_steers_python_decisions_toward_the_goal_frame(fixture_package, tmp_path):
    """goal45, named by the package's model.json or by Policy's
    direction_filter, moves toward where the goal image shows the part (the
    steer package's own AoT would go -x) and refuses to explore; a
    misspelt filter is a ValueError naming the choices."""
    import shutil

    steer = Path(fixture_package) / "steer"
    package = tmp_path / "steer-goal45"
    shutil.copytree(steer, package)
    meta = json.loads((package / "model.json").read_text())
    meta["direction_filter"] = "goal45"
    (package / "model.json").write_text(json.dumps(meta))
    plain = umpnet.Policy(str(steer))
    h, w = plain.resolution
    now, goal = panel_image(h, w, 0.0, 1.2), panel_image(h, w, 0.25, 1.2)
    assert plain.decide(now, goal, (h // 2, w // 2), mode="goal")["direction"][0] < -0.9
    for pol in (umpnet.Policy(str(package)), umpnet.Policy(str(steer), direction_filter="goal45")):
        out = pol.decide(now, goal, (h // 2, w // 2), mode="goal")
        assert out["direction"][0] >= np.sqrt(0.5), out["direction"]
        with pytest.raises(ValueError, match="goal45"):
            pol.decide(now, now, (h // 2, w // 2), mode="explore")
    with pytest.raises(ValueError, match=r"direction_filter: .*unknown direction filter `goal90`.*goal45"):
        umpnet.Policy(str(steer), direction_filter="goal90")


def test_grasp_rule_replaces_the_packages_and_the_movable_one_needs_a_joint_net(fixture_package, tmp_path):
    """grasp_rule overrides model.json's `grasp` as editing it does; the
    movable weighting on a package without a JointNet, or a misspelt rule,
    is a ValueError that says which."""
    import shutil

    joint = Path(fixture_package) / "joint"
    with pytest.raises(ValueError, match=r"grasp_rule: .*unknown grasp rule `movable`.*affordance_times_movable"):
        umpnet.Policy(str(joint), grasp_rule="movable")
    with pytest.raises(ValueError, match=r"grasp_rule: .*files\.joint"):
        umpnet.Policy(str(Path(fixture_package) / "steer"), grasp_rule="affordance_times_movable")
    shipped = Path(__file__).resolve().parents[3] / "models" / "umpnet-small"
    edited = tmp_path / "edited"
    shutil.copytree(shipped, edited)
    meta = json.loads((edited / "model.json").read_text())
    assert meta["grasp"] == "affordance_times_movable_lever"
    meta["grasp"] = "affordance"
    (edited / "model.json").write_text(json.dumps(meta))
    by_meta, by_arg = umpnet.Policy(str(edited)), umpnet.Policy(str(shipped), grasp_rule="affordance")
    env = umpnet.Env(seed=4, resolution=by_meta.resolution)
    for _ in range(3):
        image = env.reset()["image"].copy()
        assert by_meta.position(image) == by_arg.position(image)


def test_decide_reads_the_grippers_motion_between_calls_for_onward45(fixture_package):
    """decide(gripper=...) gives the runtime how the gripper went since the
    last call: onward45 then moves along exactly that way and calls it forward; the
    first call, and a gripper that hardly moved, leave the heads their
    choice; a gripper that is not three finite numbers is a ValueError."""
    pol = umpnet.Policy(str(Path(fixture_package) / "steer"), direction_filter="onward45")
    h, w = pol.resolution
    image = panel_image(h, w, 0.0, 1.2)
    pixel = (h // 2, w // 2)
    first = pol.decide(image, image, pixel, gripper=[0.0, 0.0, 1.2])
    assert min(first["distance"]) >= 0.0  # nothing ruled out before a motion
    went = np.array([0.0, 0.6, -0.8])
    out = pol.decide(image, image, pixel, moved=True, gripper=list(np.array([0.0, 0.0, 1.2]) + 0.1 * went))
    np.testing.assert_allclose(out["direction"], went, atol=1e-5)  # the motion itself, not the heads' pick
    kept = np.asarray(out["candidates"]) @ went >= np.sqrt(0.5)
    assert set(np.asarray(out["aot"])[kept]) == {1}
    assert (np.asarray(out["distance"])[~kept] == -1.0).all()
    still = pol.decide(image, image, pixel, moved=False, gripper=list(np.array([0.0, 0.0, 1.2]) + 0.11 * went))
    assert min(still["distance"]) >= 0.0
    for bad in ([0.0, 1.0], [0.0, float("nan"), 1.0]):
        with pytest.raises(ValueError, match=r"gripper = .*three finite numbers"):
            pol.decide(image, image, pixel, gripper=bad)


def test_torch_optimizer_after_rendering_in_the_same_process():
    """umpnet_train loads torch's lazy native parts before any environment renders
    (Mesa's LLVM then torch's segfaulted); check it in a fresh process."""
    import subprocess
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


def _gym_returns(env_id, policy, episodes=6):
    import gymnasium as gym  # a requirement (train_py/requirements.txt), never skipped
    import umpnet.gym  # noqa: F401  (registers the ids)

    env = gym.make(env_id, resolution=RES, category=["Door", "StorageFurniture", "Microwave"])
    rng = np.random.default_rng(0)
    returns, successes = [], []
    for k in range(episodes):
        env.reset(seed=k)
        total, done, info = 0.0, False, {}
        inner = env.unwrapped._env
        while not done:
            phase = env.unwrapped._phase
            if policy == "oracle":
                a = inner.scripted_action("oracle")
                if a is None:
                    break
            else:
                a = inner.scripted_action("random") if phase == 0 else rng.normal(size=3)
            action = {"phase": phase, "pixel": np.zeros(2, dtype=np.int64), "direction": np.zeros(3, dtype=np.float32)}
            if phase == 0:
                action["pixel"] = np.array(a)
            else:
                action["direction"] = np.asarray(a, dtype=np.float32)
            _, reward, terminated, truncated, info = env.step(action)
            total += reward
            done = terminated or truncated
        returns.append(total)
        successes.append(bool(info.get("success")))
    return np.mean(returns), np.mean(successes)


@pytest.mark.parametrize("env_id", ["umpnet/Goal-v0", "umpnet/Explore-v0"])
def test_gym_rewards_pay_the_oracle_and_not_random(env_id):
    oracle, oracle_success = _gym_returns(env_id, "oracle")
    random, _ = _gym_returns(env_id, "random")
    assert oracle > 1.0, oracle
    assert oracle > random + 1.0, (oracle, random)
    # The oracle reaches the goal, or (exploring) a joint limit, which ends the episode.
    assert oracle_success >= (0.8 if env_id == "umpnet/Goal-v0" else 0.5), oracle_success


def test_gym_budget_and_info():
    import gymnasium as gym  # a requirement (train_py/requirements.txt), never skipped
    import umpnet.gym  # noqa: F401

    env = gym.make("umpnet/Explore-v0", resolution=RES, category=["Kettle"])
    assert env.spec.max_episode_steps == 16
    _, info = env.reset(seed=1)
    assert info["success"] is False and info["elapsed_steps"] == 0
    assert env.unwrapped._budget() == 3  # the paper's budget for a Kettle


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


def test_vecenv_observations_and_info_match_env_and_are_numpy():
    # One category by name works as a list of one does.
    single = umpnet.Env(category="Microwave", resolution=RES, seed=2)
    vec = umpnet.VecEnv(2, category="Microwave", resolution=RES, seed=2)
    obs = vec.reset()
    first = single.reset()
    assert obs["intrinsics"].shape == (2, 3, 3) and obs["world_from_camera"].shape == (2, 4, 4)
    # The same seed gives the same scene, so the same camera, as Env's.
    np.testing.assert_array_equal(obs["intrinsics"][0], first["intrinsics"])
    np.testing.assert_array_equal(obs["world_from_camera"][0], first["world_from_camera"])
    _, info = vec.step_position(np.array(vec.scripted_actions("oracle")))
    assert isinstance(info["valid"], np.ndarray) and info["valid"].dtype == bool
    _, labels, sinfo = vec.step_direction(np.array(vec.scripted_actions("oracle"), dtype=np.float32))
    for flags in (labels["moved"], sinfo["active"], sinfo["suction_lost"]):
        assert isinstance(flags, np.ndarray) and flags.dtype == bool and flags.shape == (2,)
    with pytest.raises(ValueError, match="non-empty list"):
        umpnet.VecEnv(2, category=[])
    with pytest.raises(ValueError, match="Cupboard"):
        umpnet.Env(category="Cupboard")


@pytest.mark.parametrize("renderer", ["wgpu", "cpu"])
def test_batched_rendering_gives_the_same_observations_bit_for_bit(renderer):
    """batch_render=True (the default: physics in parallel, then every frame
    in one wgpu submission, or CPU frames in parallel) against each
    environment drawing its own frame, through grasps, moves and the mixed
    step with autoresets."""
    n = 3
    envs = [umpnet.VecEnv(n, seed=9, resolution=RES, renderer=renderer, batch_render=b) for b in (True, False)]
    same = lambda x, y: all(x[k].tobytes() == y[k].tobytes() for k in x)
    a, b = (e.reset() for e in envs)
    assert same(a, b)
    px = np.array(envs[0].scripted_actions("oracle"), np.int64)
    assert px.tolist() == np.array(envs[1].scripted_actions("oracle"), np.int64).tolist()
    (a, ia), (b, ib) = (e.step_position(px) for e in envs)
    assert same(a, b) and ia["valid"].tolist() == ib["valid"].tolist()
    rng = np.random.default_rng(0)
    for _ in range(3):
        d = rng.normal(size=(n, 3)).astype(np.float32)
        (a, la, _), (b, lb, _) = (e.step_direction(d) for e in envs)
        assert same(a, b) and la["r_dist"].tobytes() == lb["r_dist"].tobytes()
    # The mixed step: environment 0 resets, then grasps; the others move.
    phase = np.array([0, 1, 1])
    kinds = set()
    for reset in ([True, False, False], [False, False, False]):
        dirs = rng.normal(size=(n, 3)).astype(np.float32)
        (a, ia), (b, ib) = (e.step_mixed(np.array(reset), phase, px, dirs) for e in envs)
        assert same(a, b) and ia["kind"].tolist() == ib["kind"].tolist()
        kinds |= set(ia["kind"].tolist())
    assert kinds == {1, 2, 3}, kinds  # reset, grasp and move were all drawn


def test_a_failed_environment_in_a_batched_step_leaves_the_others_usable():
    """One bad pixel fails the step with a ValueError naming it; the other
    environment's grasp happened and was drawn, so it moves on the next step
    and its observation matches a lone Env's."""
    vec = umpnet.VecEnv(2, resolution=RES, seed=1)
    vec.reset()
    px = np.array(vec.scripted_actions("oracle"), np.int64)
    bad = px.copy()
    bad[1] = [1000, 1000]
    with pytest.raises(ValueError, match=r"pixel \(row 1000, col 1000\) outside"):
        vec.step_position(bad)
    single = umpnet.Env(resolution=RES, seed=1)
    single.reset()
    single.step_position(*px[0])
    d = np.array([[0.0, -1.0, 0.0]] * 2, np.float32)
    obs, labels, info = vec.step_direction(d)
    assert info["active"].tolist() == [True, False]
    o, lab, _ = single.step_direction(d[0].tolist())
    assert np.array_equal(obs["image"][0], o["image"]) and labels["r_dist"][0] == pytest.approx(lab["r_dist"])


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


def test_observations_are_reused_buffers_equal_to_fresh_copies():
    """The zero-copy path: every step rewrites the same arrays in place; the
    reference is written at reset only; copy=True gives the same values, bit
    for bit, in fresh arrays."""
    views, fresh = umpnet.VecEnv(2, resolution=RES, seed=4), umpnet.VecEnv(2, resolution=RES, seed=4, copy=True)
    a, b = views.reset(), fresh.reset()
    pointers = {k: v.ctypes.data for k, v in a.items()}
    trace = []
    for k in a:
        assert a[k].tobytes() == b[k].tobytes(), k
    for t in range(4):
        trace.append(b["image"])
        if t == 0:
            px = np.array(views.scripted_actions("oracle"), np.int64)
            a, ia = views.step_position(px)
            b, ib = fresh.step_position(px)
            assert list(ia["valid"]) == list(ib["valid"])
        else:
            # A sentinel in the reference survives the step: the step did not rewrite it.
            saved = a["reference"][0, 0, 0, 0]
            a["reference"][0, 0, 0, 0] = 123.0
            d = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0]], np.float32)
            a, _, _ = views.step_direction(d)
            b, _, _ = fresh.step_direction(d)
            assert a["reference"][0, 0, 0, 0] == 123.0
            a["reference"][0, 0, 0, 0] = saved
            for k in a:
                assert a[k].tobytes() == b[k].tobytes(), (t, k)
        assert {k: v.ctypes.data for k, v in a.items()} == pointers, "buffers were reallocated"
    # copy=True arrays are independent: the first one kept its values.
    assert not np.shares_memory(trace[0], trace[-1])
    assert trace[0].tobytes() != trace[-1].tobytes()
    # Single environments behave the same way.
    e, f = umpnet.Env(resolution=RES, seed=2), umpnet.Env(resolution=RES, seed=2, copy=True)
    o, p = e.reset(), f.reset()
    assert all(o[k].tobytes() == p[k].tobytes() for k in o)
    o2, _ = e.step_position(*e.scripted_action("oracle"))
    assert o2["image"] is o["image"]
    # observe() renders the unchanged state again: the same observation, bit for bit.
    kept = {k: v.copy() for k, v in o2.items()}
    o3 = e.observe()
    assert o3["image"] is o["image"] and all(o3[k].tobytes() == kept[k].tobytes() for k in kept)


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


def test_a_gym_observation_carries_the_gripper_pixel_the_shipped_policy_needs():
    import gymnasium as gym

    shipped = str(Path(__file__).resolve().parents[3] / "models" / "umpnet-small")
    policy = umpnet.Policy(shipped, seed=0)
    env = gym.make("umpnet/Goal-v0", resolution=policy.resolution, category=["Door"])
    obs, _ = env.reset(seed=1)
    assert tuple(obs["gripper_pixel"]) == (-1, -1) and env.observation_space.contains(obs)
    row, col = policy.position(obs["image"], obs["reference"])
    grasp = {"phase": 0, "pixel": np.array([row, col]), "direction": np.zeros(3, np.float32)}
    obs, _, terminated, _, info = env.step(grasp)
    assert info["valid"] and not terminated, info
    # The gripper is where the policy grasped (the suction point, projected back).
    assert np.abs(obs["gripper_pixel"] - [row, col]).max() <= 2, (obs["gripper_pixel"], (row, col))
    np.testing.assert_array_equal(obs["gripper_pixel"], env.unwrapped._obs["gripper_pixel"])
    assert env.observation_space.contains(obs)
    # With it, the policy's direction comes from public observation fields alone.
    decision = policy.direction_batch(
        obs["image"][None], obs["reference"][None], obs["gripper_pixel"][None], mode="goal"
    )[0]
    obs, *_ = env.step({"phase": 1, "pixel": np.zeros(2, np.int64), "direction": np.asarray(decision["direction"])})
    assert env.observation_space.contains(obs)


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
