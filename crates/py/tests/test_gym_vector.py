"""The gymnasium VectorEnv over the Rust VecEnv: the same episodes, rewards,
ends and observations as separate UmpnetEnvs, with next-step autoreset."""

import json
import os
import subprocess
from pathlib import Path

import gymnasium as gym  # a requirement (train_py/requirements.txt), never skipped
import numpy as np
import pytest
import umpnet
import umpnet.gym
from gymnasium.vector import AutoresetMode
from umpnet.gym import UmpnetEnv, UmpnetVectorEnv
from umpnet.policy import SHIPPED_MODEL

RES = (48, 64)
CATEGORIES = ["Door", "StorageFurniture", "Microwave", "Kettle"]


def _action(a, phase):
    """A scripted action (pixel, direction or None for stop) as one env's action dict."""
    pixel = np.zeros(2, np.int64)
    direction = np.array([0.0, 0.0, 1.0], np.float32)
    if phase == 0:
        pixel = np.asarray(a, np.int64)
    elif a is not None:
        direction = np.asarray(a, np.float32)
    return {"phase": phase, "pixel": pixel, "direction": direction}


@pytest.mark.parametrize("task", ["goal", "exploration"])
def test_vector_env_steps_like_separate_envs_with_autoreset(task):
    n, seed = 3, 7
    venv = UmpnetVectorEnv(num_envs=n, task=task, resolution=RES, category=CATEGORIES, seed=seed)
    singles = [UmpnetEnv(task=task, resolution=RES, category=CATEGORIES, seed=seed + i) for i in range(n)]
    vobs, vinfo = venv.reset()
    for i, e in enumerate(singles):
        obs, _ = e.reset()
        assert np.array_equal(vobs["image"][i], obs["image"]) and np.array_equal(vobs["reference"][i], obs["reference"])
    assert not vinfo["success"].any() and (vinfo["elapsed_steps"] == 0).all()
    done = np.zeros(n, bool)
    resets = successes = moves = 0
    for _ in range(40):
        # Every env's scripted oracle is asked each step, in the vector and in
        # the separate envs alike, so their random streams stay in step.
        wanted = venv._vec.scripted_actions("oracle")
        assert wanted == [e._env.scripted_action("oracle") for e in singles]
        phases = vobs["phase"]
        acts = [_action(a, int(p)) for a, p in zip(wanted, phases, strict=True)]
        batched = {k: np.stack([a[k] for a in acts]) for k in ("phase", "pixel", "direction")}
        vobs, reward, term, trunc, info = venv.step(batched)
        for i, e in enumerate(singles):
            if done[i]:
                obs, sinfo = e.reset()
                assert info["reset"][i] and reward[i] == 0 and not term[i] and not trunc[i]
                assert vobs["phase"][i] == 0 and info["elapsed_steps"][i] == 0
                assert np.array_equal(vobs["reference"][i], obs["reference"])
                resets += 1
            else:
                obs, r, t, tr, sinfo = e.step(acts[i])
                assert not info["reset"][i]
                assert reward[i] == pytest.approx(r, abs=1e-9), (i, reward[i], r)
                assert (term[i], trunc[i]) == (t, tr), i
                assert info["success"][i] == sinfo["success"] and info["elapsed_steps"][i] == sinfo["elapsed_steps"]
                successes += int(sinfo["success"])
                moves += int(acts[i]["phase"] == 1)
            assert np.array_equal(vobs["image"][i], obs["image"]), i
            assert vobs["phase"][i] == obs["phase"]
        done = term | trunc
    # The comparison covered grasps, moves, successes and autoresets.
    assert resets >= 3 and successes >= 2 and moves >= 10, (resets, successes, moves)


def test_make_vec_gives_the_rust_vector_env_with_gymnasium_spaces():
    venv = gym.make_vec("umpnet/Goal-v0", num_envs=2, resolution=RES, category=CATEGORIES)
    assert isinstance(venv.unwrapped, UmpnetVectorEnv)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert venv.num_envs == 2
    assert venv.single_observation_space["image"].shape == (*RES, 10)
    assert venv.observation_space["image"].shape == (2, *RES, 10)
    obs, info = venv.reset(seed=3)
    assert venv.observation_space.contains(obs)
    assert info["success"].shape == (2,) and info["elapsed_steps"].dtype == np.int64
    venv.action_space.seed(0)
    ended = 0
    for _ in range(30):
        obs, reward, term, trunc, info = venv.step(venv.action_space.sample())
        assert venv.observation_space.contains(obs)
        assert reward.shape == (2,) and reward.dtype == np.float64 and np.isfinite(reward).all()
        assert term.dtype == bool and trunc.dtype == bool and info["success"].dtype == bool
        ended += int((term | trunc).sum())
    assert ended > 0  # random pixels mostly miss: episodes end and restart
    # The spec's step limit reaches the vector env (gymnasium passes it on).
    assert venv.unwrapped.max_episode_steps == venv.spec.max_episode_steps


def test_same_seed_same_vector_episodes():
    def run():
        venv = UmpnetVectorEnv(num_envs=2, task="exploration", resolution=RES, category=CATEGORIES, seed=1)
        venv.reset()
        venv.action_space.seed(5)
        out = []
        for _ in range(12):
            obs, reward, term, trunc, _ = venv.step(venv.action_space.sample())
            out.append((obs["image"].copy(), reward, term, trunc))
        return out

    for (a, ra, ta, tra), (b, rb, tb, trb) in zip(run(), run(), strict=True):
        assert np.array_equal(a, b) and np.array_equal(ra, rb) and np.array_equal(ta, tb) and np.array_equal(tra, trb)


def test_mixed_step_refuses_bad_shapes_and_pixels_by_name():
    vec = umpnet.VecEnv(2, resolution=RES, category="Door")
    vec.reset()
    ok = {
        "reset": np.zeros(2, bool),
        "phase": np.zeros(2, np.int64),
        "pixels": np.zeros((2, 2), np.int64),
        "directions": np.zeros((2, 3), np.float32),
    }
    with pytest.raises(ValueError, match=r"phase has shape \[3\], expected \[2\]"):
        vec.step_mixed(**{**ok, "phase": np.zeros(3, np.int64)})
    with pytest.raises(ValueError, match="pixels row 1"):
        vec.step_mixed(**{**ok, "pixels": np.array([[0, 0], [-1, 0]], np.int64)})
    with pytest.raises(TypeError, match="bool"):
        vec.step_mixed(**{**ok, "reset": np.zeros(2, np.int64)})
    with pytest.raises(ValueError, match="task"):
        UmpnetVectorEnv(num_envs=2, task="explore")


def test_vector_rendering_follows_gymnasium():
    venv = gym.make_vec("umpnet/Explore-v0", num_envs=2, resolution=RES, category=CATEGORIES, render_mode="rgb_array")
    assert venv.render_mode == "rgb_array" and venv.metadata["render_fps"] > 0
    venv.reset(seed=3)
    frames = venv.render()
    # A size people watch by default, whatever the observation's.
    assert frames.shape == (2, 480, 640, 3) and frames.dtype == np.uint8 and frames.max() > 0
    with pytest.raises(ValueError, match="render_mode 'window'"):
        gym.make_vec("umpnet/Explore-v0", num_envs=1, resolution=RES, render_mode="window")
    env = gym.make("umpnet/Explore-v0", resolution=RES, render_mode="rgb_array", render_size=None)
    obs, _ = env.reset(seed=0)
    assert np.array_equal(env.render(), umpnet.gym.rgb(obs["image"]))
    assert env.metadata["render_fps"] == venv.metadata["render_fps"]


def _no_display(monkeypatch):
    for var in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER"):
        monkeypatch.delenv(var, raising=False)


def test_human_mode_without_a_window_writes_each_frame_and_says_where(monkeypatch, tmp_path, caplog):
    """render_mode='human' where no window can open (CI, a server): every
    reset and step replaces one PNG, the first says where in a notice, and
    render() returns None, as gymnasium's human mode does."""
    from PIL import Image

    _no_display(monkeypatch)
    env = gym.make("umpnet/Goal-v0", resolution=(24, 32), render_mode="human", category="Door")
    with caplog.at_level("WARNING", logger="umpnet"):
        env.reset(seed=2)
    path = env.unwrapped._viewer.frame_path
    notices = [r.getMessage() for r in caplog.records if r.name == "umpnet"]
    assert len(notices) == 1 and "no window can open, no display" in notices[0] and str(path) in notices[0]
    assert env.unwrapped._viewer.backend == "file"
    first = np.asarray(Image.open(path))
    assert first.shape == (480, 640, 3)
    pixel = np.array(env.unwrapped._env.scripted_action("oracle"))
    env.step({"phase": 0, "pixel": pixel, "direction": np.zeros(3, np.float32)})
    assert not np.array_equal(np.asarray(Image.open(path)), first), "the step's frame (with the gripper) was not shown"
    assert env.render() is None
    assert len([r for r in caplog.records if r.name == "umpnet"]) == 1, "the notice is said more than once"
    env.close()
    # A file asked for: no warning; the vector env shows its environments as one grid.
    import warnings

    from gymnasium.utils.env_checker import check_env

    frame = tmp_path / "live" / "frame.png"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        single = gym.make("umpnet/Goal-v0", resolution=(24, 32), render_mode="human", human_frame_path=frame)
        check_env(single.unwrapped)
        venv = gym.make_vec("umpnet/Goal-v0", num_envs=3, resolution=(24, 32), render_mode="human",
                            render_size=(48, 64), human_frame_path=frame, category="Door")  # fmt: skip
        venv.reset(seed=2)
    grid = np.asarray(Image.open(frame))
    assert grid.shape == (2 * 48, 2 * 64, 3)  # three environments in a 2 x 2 grid
    rgb_venv = gym.make_vec("umpnet/Goal-v0", num_envs=3, resolution=(24, 32), render_mode="rgb_array",
                            render_size=(48, 64), category="Door")  # fmt: skip
    rgb_venv.reset(seed=2)
    frames = rgb_venv.render()
    assert np.array_equal(grid[:48, 64:], frames[1]) and np.array_equal(grid[48:, :64], frames[2])
    assert not grid[48:, 64:].any(), "the empty cell is not black"
    venv.close()


def test_human_mode_opens_a_window_where_a_display_is(monkeypatch):
    """With pygame and a display (SDL's dummy driver here), the frames go to a
    window, shown as render() would return them."""
    import pygame  # a test requirement (train_py/requirements.txt), never skipped

    _no_display(monkeypatch)
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    env = gym.make("umpnet/Explore-v0", resolution=(24, 32), render_mode="human", render_size=(60, 80),
                   category="Door")  # fmt: skip
    env.reset(seed=1)
    viewer = env.unwrapped._viewer
    assert viewer.backend == "window" and viewer.frame_path is None
    shown = pygame.surfarray.array3d(pygame.display.get_surface()).swapaxes(0, 1)
    assert np.array_equal(shown, env.unwrapped._frame())
    env.close()
    assert not pygame.display.get_init(), "close() left the window open"


def test_policy_act_drives_the_gym_environments_from_the_observation_alone():

    shipped = str(Path(__file__).resolve().parents[3] / "models" / "umpnet-small")
    policy = umpnet.Policy(shipped, seed=0)
    env = gym.make("umpnet/Goal-v0", resolution=policy.resolution, category=["Door"])
    successes, valid = 0, 0
    for seed in range(6):
        obs, _ = env.reset(seed=seed)
        action = policy.act(obs, "goal")
        assert env.action_space.contains(action)
        obs, _, terminated, truncated, info = env.step(action)
        valid += bool(info["valid"])
        while not (terminated or truncated):
            action = policy.act(obs, "goal")
            assert action["phase"] == 1 and abs(np.linalg.norm(action["direction"]) - 1) < 1e-4
            obs, _, terminated, truncated, info = env.step(action)
        successes += bool(info["success"])
    # The shipped model grasps the door and reaches some goals (0.56 goal
    # success on the test categories; doors are among its better ones).
    assert valid >= 5 and successes >= 1, (valid, successes)
    with pytest.raises(ValueError, match="task 'push'"):
        policy.act(obs, "push")


@pytest.mark.parametrize("doc", ["README.md", "docs/python.md"])
def test_documented_python_runs_as_written(doc, tmp_path, monkeypatch):
    """Every ```python block of the front page and of docs/python.md, as
    written, from the repository root (where data/objects is generated)."""
    root = Path(__file__).resolve().parents[3]
    text = (root / doc).read_text()
    blocks = [b.split("```", 1)[0] for b in text.split("```python\n")[1:]]
    assert blocks, f"{doc} has no python block"
    if any("data/objects/" in b for b in blocks):
        urdf = root / "data" / "objects" / "Microwave" / "4" / "mobility.urdf"
        if not urdf.is_file():
            # The block names a generated object: generate that family here.
            subprocess.run(
                [
                    os.environ.get("UMPNET_BIN", str(root / "target/release/umpnet")),
                    "objects",
                    "generate",
                    "--out",
                    str(tmp_path / "data/objects"),
                    "--per-category",
                    "5",
                    "--categories",
                    "Microwave",
                ],
                check=True,
                capture_output=True,
            )
            blocks = [b.replace("data/objects/", str(tmp_path / "data/objects") + "/") for b in blocks]
    monkeypatch.chdir(root)
    for block in blocks:
        exec(compile(block, f"{doc} (python block)", "exec"), {})  # noqa: S102  (the docs, run as written)


@pytest.mark.parametrize(
    ("task", "direction_filter", "mirror_average"),
    [
        ("goal", None, False),
        ("exploration", None, False),
        ("goal", "goal45", False),
        ("exploration", "onward45", False),
        ("goal", None, True),
    ],
)
def test_the_shipped_policy_through_gym_makes_the_moves_umpnet_eval_made(
    task, direction_filter, mirror_average, tmp_path
):
    """On the benchmark's scenes and seeds, the shipped policy driven through
    gymnasium by Policy.act (with each step's info) makes exactly the moves
    `umpnet eval` recorded and ends its episodes the same way; under the
    filters that read the gripper's own motion (from ``info``) and the
    grasped part's joint (read at the grasp) too, and scoring each move on
    the mirrored scene as well (``mirror_average``, ``--mirror-average``)."""
    root = Path(__file__).resolve().parents[3]
    binary = os.environ.get("UMPNET_BIN", str(root / "target/release/umpnet"))
    out = tmp_path / "eval"
    filters = ["--direction-filter", direction_filter] if direction_filter else []
    filters += ["--mirror-average"] if mirror_average else []
    subprocess.run(
        [binary, "eval", "--task", task, "--categories", "Door,Microwave,Switch", "--episodes-per-category", "3",
         "--policies", "umpnet", "--model", str(SHIPPED_MODEL), "--out", str(out), *filters],
        check=True, capture_output=True,
    )  # fmt: skip
    episodes = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    episodes = [e for e in episodes if e["policy"] == "umpnet"]
    assert len(episodes) == 9
    policy = umpnet.Policy.default(direction_filter=direction_filter, mirror_average=mirror_average)
    env = gym.make(f"umpnet/{'Goal' if task == 'goal' else 'Explore'}-v0", resolution=policy.resolution)
    compared = 0
    for e in episodes:
        ep = e["episode"]
        _, policy_seed = umpnet.benchmark_seeds(task, e["category"], e["index"])
        policy.reset(policy_seed)
        obs, info = env.reset(options={"scene": ep["scene"]})
        action = policy.act(obs, task)
        assert tuple(action["pixel"]) == tuple(ep["pixel"]), (e["category"], e["index"])
        obs, _, terminated, truncated, info = env.step(action)
        moves = []
        while not (terminated or truncated):
            action = policy.act(obs, task, info)
            if policy.stopped:
                assert ep["stopped_early"], (e["category"], e["index"])
                break
            moves.append(action["direction"])
            obs, _, terminated, truncated, info = env.step(action)
        recorded = [s["record"]["direction"] for s in ep["steps"]]
        assert len(moves) == len(recorded), (e["category"], e["index"], len(moves), len(recorded))
        assert np.allclose(moves, recorded, atol=1e-5) if recorded else True
        if task == "goal":
            # Two successes: the env's ends the episode by the protocol (within
            # the threshold of the goal, or across it); eval's metric is also the
            # paper's, a final normalised distance under 0.1, which an episode
            # the policy stopped or the budget ended can meet without the first.
            goal = ep["scene"]["goal"]
            start, target = ep["scene"]["joints"][goal["joint"]], goal["joints"][goal["joint"]]
            joints = info.get("joints", ep["scene"]["joints"])  # no move made: where the scene began
            final = abs(joints[goal["joint"]] - target) / max(abs(target - start), 1e-6)
            assert (bool(info["success"]) or final < 0.1) == ep["metrics"]["success"], (e["category"], e["index"])
        compared += len(recorded)
    assert compared >= 9  # the episodes made moves, not only grasps


@pytest.mark.parametrize("obs_mode", ["image", "rgbd", "pointcloud", "state"])
def test_every_obs_mode_passes_the_env_checker_and_says_what_the_image_says(obs_mode):
    """ManiSkill's observation modes: each passes gymnasium's env checker
    (render included) without warnings, fits its space through an episode in
    both env classes, and carries the same facts as the 10-channel image."""
    import warnings

    from gymnasium.utils.env_checker import check_env

    res = (24, 32)
    env = gym.make("umpnet/Goal-v0", resolution=res, obs_mode=obs_mode, render_mode="rgb_array", category="Door")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    obs, _ = env.reset(seed=5)
    image_env = gym.make("umpnet/Goal-v0", resolution=res, category="Door")
    image, _ = image_env.reset(seed=5)
    img = image["image"]
    if obs_mode == "rgbd":
        assert np.array_equal(obs["depth"][..., 0], img[..., 9]) and obs["rgb"].dtype == np.uint8
        assert np.array_equal(obs["rgb"], (np.clip(img[..., 3:6], 0, 1) * 255).astype(np.uint8))
    elif obs_mode == "pointcloud":
        assert np.array_equal(obs["xyz"], img[..., 0:3].reshape(-1, 3))
        assert np.array_equal(obs["valid"].astype(bool), img[..., 9].reshape(-1) > 0)
    elif obs_mode == "state":
        scene = env.unwrapped._env.scene
        n = len(scene["joints"])
        assert np.allclose(obs["joints"][:n], scene["joints"]) and obs["joint_mask"].sum() == n
        assert np.allclose(obs["reference_joints"][:n], scene["goal"]["joints"]) and obs["grasped_joint"] == -1
    # Through an episode, in the single and the vector env alike.
    scripted = umpnet.Env("Door", seed=5, resolution=res, task="goal")
    scripted.reset()
    row, col = scripted.scripted_action("oracle")
    obs, *_ = env.step({"phase": 0, "pixel": np.array([row, col]), "direction": np.zeros(3, np.float32)})
    assert env.observation_space.contains(obs)
    if obs_mode == "state":
        assert obs["grasped_joint"] >= 0
        before = obs["joints"].copy()
        obs, *_ = env.step({"phase": 1, "pixel": np.zeros(2, np.int64), "direction": np.array([0, -1, 0], np.float32)})
        assert env.observation_space.contains(obs) and not np.array_equal(before, obs["joints"])
    venv = gym.make_vec("umpnet/Explore-v0", num_envs=2, resolution=res, obs_mode=obs_mode)
    vobs, _ = venv.reset(seed=1)
    assert venv.observation_space.contains(vobs)
    vobs, *_ = venv.step(venv.action_space.sample())
    assert venv.observation_space.contains(vobs)
    with pytest.raises(ValueError, match="obs_mode 'depth'"):
        gym.make("umpnet/Goal-v0", obs_mode="depth")


@pytest.mark.parametrize("fmt", ["gif", "mp4"])
def test_record_episode_writes_one_whole_video_per_episode(fmt, tmp_path):
    """RecordEpisode writes each episode's rendered frames (reset plus one per
    step), named in order, and says where in the last step's info."""
    from PIL import Image

    small = {
        "resolution": (24, 32),
        "render_mode": "rgb_array",
        "render_size": None,
        "category": "Door",
        "max_steps": 3,
    }
    env = umpnet.gym.RecordEpisode(
        gym.make("umpnet/Explore-v0", **small),
        tmp_path / "videos",
        format=fmt,
        scale=2,
    )
    for episode in range(2):
        env.reset(seed=episode)
        steps, done = 0, False
        while not done:
            action = env.action_space.sample()
            action["phase"] = 0 if steps == 0 else 1
            if steps == 0:  # a grasp on the door, so that every step changes the picture
                action["pixel"] = np.array(env.unwrapped._env.scripted_action("oracle"))
            _, _, terminated, truncated, info = env.step(action)
            steps, done = steps + 1, terminated or truncated
        video = Path(info["video"])
        assert video.name == f"episode_{episode:04d}.{fmt}" and video.is_file()
        if fmt == "gif":
            gif = Image.open(video)
            # Pillow merges identical frames into one of their summed duration:
            # the playback time says how many frames were written.
            total = 0
            for k in range(gif.n_frames):
                gif.seek(k)
                total += gif.info["duration"]
            assert total == (steps + 1) * 250 and gif.size == (64, 48)
        else:
            import imageio_ffmpeg

            reader = imageio_ffmpeg.read_frames(str(video))
            meta = next(reader)
            assert meta["size"] == (64, 48) and sum(1 for _ in reader) == steps + 1
    assert sorted(p.name for p in (tmp_path / "videos").iterdir()) == [f"episode_0000.{fmt}", f"episode_0001.{fmt}"]
    env.close()
    with pytest.raises(ValueError, match="render_mode='rgb_array'"):
        umpnet.gym.RecordEpisode(gym.make("umpnet/Explore-v0"), tmp_path)


def test_render_size_draws_the_scene_again_for_people(tmp_path):
    """render_size: render() draws the current state at that size from the
    observations' camera, gripper included; a larger picture of the same
    scene, refused by name at a nonsensical size."""
    env = gym.make("umpnet/Goal-v0", resolution=(24, 32), render_mode="rgb_array", render_size=(240, 320),
                   category="Door")  # fmt: skip
    obs, _ = env.reset(seed=2)
    big = env.render()
    assert big.shape == (240, 320, 3) and big.dtype == np.uint8
    # The same picture as the observation, at ten times the size: the small
    # one's colours, averaged over each 10 x 10 block, agree on most pixels.
    small = (np.clip(obs["image"][..., 3:6], 0, 1) * 255).astype(float)
    blocks = big.reshape(24, 10, 32, 10, 3).mean(axis=(1, 3))
    assert np.mean(np.abs(blocks - small).max(axis=-1) < 40) > 0.9
    pixel = np.array(env.unwrapped._env.scripted_action("oracle"))
    env.step({"phase": 0, "pixel": pixel, "direction": np.zeros(3, np.float32)})
    assert not np.array_equal(env.render(), big), "the gripper does not show"
    with pytest.raises(ValueError, match="render size"):
        env.unwrapped._env.render_rgb(0, 10)
    venv = gym.make_vec("umpnet/Goal-v0", num_envs=2, resolution=(24, 32), render_mode="rgb_array",
                        render_size=(48, 64), category="Door")  # fmt: skip
    venv.reset(seed=2)
    frames = venv.render()
    assert frames.shape == (2, 48, 64, 3) and frames.dtype == np.uint8
    single = gym.make("umpnet/Goal-v0", resolution=(24, 32), render_mode="rgb_array", render_size=(48, 64),
                      category="Door")  # fmt: skip
    single.reset(seed=2)
    assert np.array_equal(frames[0], single.render()), "environment 0 of the vector env is not the single env"
