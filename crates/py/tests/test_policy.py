"""The Python bindings' `Policy`: decisions on an environment's
observations, the joint read from one frame, the mirror, the direction
filters and grasp rules, and an episode's memory across `decide` calls."""

import json
from pathlib import Path

import numpy as np
import pytest
import umpnet

RES = (48, 64)


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
