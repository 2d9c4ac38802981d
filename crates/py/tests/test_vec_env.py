"""The Python bindings' `VecEnv`: the same as separate `Env`s, batched
rendering bit for bit, one failed environment leaving the others usable,
and observations in reused buffers."""

import numpy as np
import pytest
import umpnet

RES = (48, 64)


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
