"""End-to-end tests of `umpnet infer`: one decision from files a robot's
camera wrote, sessions across a robot loop's calls, the joint read from one
frame, and the frames, cameras and depths it refuses."""

import json
import math
from pathlib import Path

import numpy as np
from PIL import Image
from umpnet_cli import ROOT, run


def test_learned_policy_episode_and_infer(tmp_path, fixture_package):
    fixture = fixture_package
    out = json.loads(run("--json", "explore", "--category", "Door", "--policy", "umpnet", "--model", fixture).stdout)
    assert out["policy"] == "umpnet" and out["scene"]["category"] == "Door"
    # The shipped model on four door scenes: a grasp on the door every time,
    # directions that are unit vectors taken from its own scored candidates,
    # and doors that move; the same command gives the same episode.
    for seed in range(4):
        args = ("--json", "explore", "--category", "Door", "--seed", str(seed), "--policy", "umpnet")
        text = run(*args).stdout
        ep = json.loads(text)
        assert ep["valid_position"] and ep["steps"], (seed, ep["pixel"])
        for step in ep["steps"]:
            d = np.array(step["record"]["direction"])
            assert abs(np.linalg.norm(d) - 1) < 1e-5
            cands = step["candidates"]
            assert len(cands["directions"]) == len(cands["distance"]) == len(cands["aot"]) > 1
            assert min(np.abs(np.array(cands["directions"]) - d).max(axis=1)) < 1e-6
        assert len(ep["metrics"]["unique_states"]) == ep["budget"] and ep["metrics"]["novel_state_ratio"] > 0
        assert any(step["record"]["labels"]["moved"] for step in ep["steps"])
        assert run(*args).stdout == text
    run("render", "--category", "Microwave", "--seed", "3", "--resolution", "96x128", "--out", str(tmp_path))
    cam = json.loads((tmp_path / "camera.json").read_text())
    k = cam["intrinsics"]
    pose = ",".join(str(v) for row in cam["world_from_camera"] for v in row)
    res = json.loads(
        run(
            "infer", "--rgb", str(tmp_path / "color.png"), "--depth", str(tmp_path / "depth.npy"),
            "--intrinsics", f"{k['fx']},{k['fy']},{k['cx']},{k['cy']}", "--camera-pose", pose, "--model", fixture,
        ).stdout
    )  # fmt: skip
    assert len(res["pixel"]) == 2 and res["mode"] == "explore"
    # Exploration never stops: there is always a unit direction.
    assert res["direction"] is not None and abs(sum(v * v for v in res["direction"]) - 1) < 1e-4
    bad = run("infer", "--rgb", str(tmp_path / "color.png"), "--depth", str(tmp_path / "depth.npy"),
              "--intrinsics", "1,2", "--camera-pose", pose, "--model", fixture, check=False)  # fmt: skip
    assert bad.returncode == 2 and "--intrinsics" in bad.stderr
    # Broken depth files are errors that name the file, never a panic.
    data = (tmp_path / "depth.npy").read_bytes()
    v2 = data[:6] + b"\x02\x00" + (len(data) - 10).to_bytes(4, "little")[:2]  # a version-2 header cut short
    for name, content in [("truncated.npy", data[:40]), ("v2.npy", v2), ("short.npy", data[:11])]:
        (tmp_path / name).write_bytes(content)
        bad = run("infer", "--rgb", str(tmp_path / "color.png"), "--depth", str(tmp_path / name),
                  "--intrinsics", f"{k['fx']},{k['fy']},{k['cx']},{k['cy']}", "--camera-pose", pose,
                  "--model", fixture, check=False)  # fmt: skip
        assert bad.returncode == 1 and name in bad.stderr and "panicked" not in bad.stderr, (name, bad.stderr)
    # render's raw depth: float32 metres and 16-bit millimetres agree, and infer reads both
    # (and float64), giving the same action.
    depth_m = np.load(tmp_path / "depth.npy")
    depth_mm = np.asarray(Image.open(tmp_path / "depth_mm.png"))
    assert depth_m.dtype == np.float32 and depth_mm.dtype == np.uint16 and depth_m.shape == depth_mm.shape == (96, 128)
    assert np.abs(depth_mm / 1000.0 - depth_m).max() < 6e-4 and (depth_m > 0).mean() > 0.5
    np.save(tmp_path / "depth64.npy", depth_m.astype(np.float64))
    Image.fromarray((depth_mm // 256).astype(np.uint8)).save(tmp_path / "depth8.png")
    camera = ["--intrinsics", f"{k['fx']},{k['fy']},{k['cx']},{k['cy']}", "--model", fixture]

    def infer(depth, *extra, pose=pose):
        return run("--json", "infer", "--rgb", str(tmp_path / "color.png"), "--depth", str(tmp_path / depth),
                   "--camera-pose", pose, *camera, *extra, check=False)  # fmt: skip

    same = [json.loads(infer(d).stdout) for d in ("depth_mm.png", "depth64.npy")]
    assert all(r["pixel"] == res["pixel"] for r in same), (same, res)
    assert "warning" not in infer("depth_mm.png").stderr
    # Millimetres read as metres put the object kilometres away: said, with the scale that fits.
    far = infer("depth_mm.png", "--depth-scale", "1")
    assert "depth_mm.png: the median depth is" in far.stderr and "1e-3 would put it at" in far.stderr, far.stderr
    # Exploration against the episode's first frame: that frame as its own
    # reference is what infer does without it; halves of a pair are refused.
    first = json.loads(infer("depth.npy").stdout)
    again = json.loads(infer("depth.npy", "--initial", str(tmp_path / "color.png"), "--initial-depth",
                             str(tmp_path / "depth.npy")).stdout)  # fmt: skip
    assert (again["pixel"], again["direction"]) == (first["pixel"], first["direction"])
    for extra, needle in [
        (("--initial", str(tmp_path / "color.png")), "--initial and --initial-depth go together"),
        (("--previous", "0,0,0"), "--previous takes x,y,z"),
        (("--previous", "1,0"), "--previous takes x,y,z"),
    ]:
        bad = infer("depth.npy", *extra)
        assert bad.returncode == 2 and needle in bad.stderr, (extra, bad.stderr)
    # Under prev90 the next move stays within 90 degrees of the last one.
    for previous in ([1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]):
        arg = ",".join(map(str, previous))
        r = json.loads(infer("depth.npy", "--direction-filter", "prev90", f"--previous={arg}").stdout)
        assert np.dot(r["direction"], previous) >= 0, (previous, r)
    # Nonsense is refused by name, never clamped or ignored.
    for args, pose_, needle in [
        (("--grasp=99999,99999",), pose, "outside the 96x128 image"),
        (("--grasp=5",), pose, "--grasp takes row,col"),
        ((), ",".join(["0"] * 16), "not a rigid transform"),
    ]:
        bad = infer("depth.npy", *args, pose=pose_)
        assert bad.returncode == 2 and needle in bad.stderr, (args, bad.stderr)
    bad = infer("depth8.png")
    assert bad.returncode == 2 and "depth8.png" in bad.stderr and "16-bit" in bad.stderr, bad.stderr


def test_documented_infer_example_runs_as_written(tmp_path):
    """docs/cli.md's render -> infer commands, as written, with the shipped model."""
    readme = (ROOT / "docs" / "cli.md").read_text()
    block = readme.split("umpnet render --category Microwave", 1)[1].split("```", 1)[0]
    lines = ("umpnet render --category Microwave" + block).replace("\\\n", " ").strip().splitlines()
    assert len(lines) == 2 and lines[1].startswith("umpnet infer"), lines
    outputs = []
    for line in lines:
        args = [a.replace("out/frame", str(tmp_path / "frame")) for a in line.split()[1:]]
        outputs.append(run("--json", *args).stdout)
    res = json.loads(outputs[1])
    assert res["mode"] == "explore" and len(res["pixel"]) == 2 and res["point_in_world"] is not None
    assert abs(sum(v * v for v in res["direction"]) - 1) < 1e-4
    # A camera.json that is not one is refused by name.
    (tmp_path / "bad.json").write_text('{"intrinsics": [1, 2]}')
    args = [a.replace("out/frame", str(tmp_path / "frame")) for a in lines[1].split()[1:]]
    args[args.index("--camera") + 1] = str(tmp_path / "bad.json")
    bad = run(*args, check=False)
    assert bad.returncode == 2 and "bad.json" in bad.stderr, bad.stderr


def test_infer_refuses_cameras_frames_and_depths_that_do_not_fit_by_name(tmp_path):
    frame = tmp_path / "frame"
    run("render", "--category", "Microwave", "--seed", "1", "--resolution", "96x128", "--out", str(frame))
    other = tmp_path / "other"
    run("render", "--category", "Microwave", "--seed", "1", "--resolution", "48x64", "--out", str(other))
    good = {"--rgb": frame / "color.png", "--depth": frame / "depth.npy", "--camera": frame / "camera.json"}

    def infer(*extra, **swap):
        paths = good | {f"--{k}": v for k, v in swap.items()}
        return run("infer", *[str(x) for kv in paths.items() for x in kv], *extra, check=False)

    assert infer().returncode == 0
    cam = json.loads(good["--camera"].read_text())

    def camera(name, **change):
        path = tmp_path / name
        path.write_text(json.dumps(cam | change))
        return path

    # A camera.json written for another image size: its intrinsics would not fit.
    p = infer(camera=camera("small.json", height=48, width=64))
    assert p.returncode == 2 and "small.json was written for 48x64 images" in p.stderr and "96x128" in p.stderr, (
        p.stderr
    )
    # Intrinsics or a translation of 1e30 parse, and describe no camera.
    k = cam["intrinsics"]
    p = infer(camera=camera("focal.json", intrinsics=k | {"fx": 1e30}))
    assert p.returncode == 2 and "focal.json" in p.stderr and "fx and fy must be in (0, 1e6]" in p.stderr, p.stderr
    far = [row[:3] + [1e30 if i == 0 else row[3]] for i, row in enumerate(cam["world_from_camera"])]
    p = infer(camera=camera("far.json", world_from_camera=far))
    assert p.returncode == 2 and "far.json" in p.stderr and "more than 1000 m from the origin" in p.stderr, p.stderr
    # A reference frame from another camera size.
    p = infer("--reference", other / "color.png", "--reference-depth", other / "depth.npy")
    assert p.returncode == 2 and "--reference" in p.stderr and "is 48x64, but the current frame" in p.stderr, p.stderr
    # Depth that no camera measures is named with its file, not blamed on the model.
    depth = np.load(good["--depth"])
    huge = tmp_path / "huge.npy"
    np.save(huge, np.where(depth > 0, 1e30, 0).astype(np.float32))
    p = infer(depth=huge)
    assert p.returncode == 2 and "huge.npy: depth 1e30 m at pixel" in p.stderr, p.stderr
    empty = tmp_path / "empty.npy"
    np.save(empty, np.zeros_like(depth))
    p = infer(depth=empty)
    assert p.returncode == 2 and "empty.npy: no pixel has a depth" in p.stderr, p.stderr


def test_infer_session_keeps_a_robot_loops_episode_across_calls(tmp_path):
    """`infer --session DIR`: the first call starts the episode (grasp and
    first move), later calls take where the gripper is and whether the last
    move moved the part; a move that moved nothing is not chosen again, a
    move that moved lifts the bans; the same calls give the same moves; a
    session refuses another model, camera or task by name."""
    run("render", "--category", "Microwave", "--seed", "3", "--resolution", "96x128", "--out", str(tmp_path / "f"))
    frame = ["--rgb", str(tmp_path / "f/color.png"), "--depth", str(tmp_path / "f/depth.npy"),
             "--camera", str(tmp_path / "f/camera.json")]  # fmt: skip

    def episode(session):
        first = json.loads(run("--json", "infer", "--session", str(session), *frame).stdout)
        assert first["session"]["step"] == 1 and first["direction"] is not None
        gripper = ",".join(f"{v:.5f}" for v in first["point_in_world"])
        second = json.loads(
            run("--json", "infer", "--session", str(session), *frame, f"--gripper={gripper}", "--moved", "false").stdout
        )
        assert second["session"] == {"dir": str(session), "step": 2, "banned": 1}
        # Within the ban's 20 degrees of the first move: not chosen again.
        cos = sum(a * b for a, b in zip(first["direction"], second["direction"]))
        assert cos < 0.94, cos
        third = json.loads(
            run("--json", "infer", "--session", str(session), *frame, f"--gripper={gripper}", "--moved", "true").stdout
        )
        assert third["session"]["banned"] == 0 and third["session"]["step"] == 3
        return [first, second, third]

    a, b = episode(tmp_path / "a"), episode(tmp_path / "b")
    strip = [{k: v for k, v in o.items() if k != "session"} for o in a]
    assert strip == [{k: v for k, v in o.items() if k != "session"} for o in b]
    s = str(tmp_path / "a")
    for extra, says in [
        ([], "--grasp row,col or --gripper x,y,z"),
        (
            [
                "--reference",
                str(tmp_path / "f/color.png"),
                "--reference-depth",
                str(tmp_path / "f/depth.npy"),
                "--grasp",
                "10,10",
            ],
            "the session explores",
        ),
        (["--gripper", "0,0,-100"], "not in front of the camera"),
    ]:
        p = run("infer", "--session", s, *frame, *extra, check=False)
        assert p.returncode == 2 and says in p.stderr, (extra, p.stderr)
    p = run("infer", "--session", str(tmp_path / "new"), *frame, "--moved", "true", check=False)
    assert p.returncode == 2 and "no session yet" in p.stderr, p.stderr


def test_infer_session_keeps_the_joint_read_where_the_grasp_was_made(tmp_path):
    """A session reads the grasped part's joint once, on its first call's frame
    (later frames show the gripper over the part), and every later call
    decides with it and reports it; a session.json whose joint has no axis is
    refused by name."""
    model = str(ROOT / "models" / "umpnet-small")
    for seed in ("3", "4"):
        run(
            "render", "--category", "Microwave", "--seed", seed, "--resolution", "96x128", "--out", str(tmp_path / seed)
        )

    def frame(seed):
        return ["--rgb", str(tmp_path / seed / "color.png"), "--depth", str(tmp_path / seed / "depth.npy"),
                "--camera", str(tmp_path / seed / "camera.json"), "--model", model]  # fmt: skip

    s = tmp_path / "s"
    first = json.loads(run("--json", "infer", "--session", str(s), *frame("3")).stdout)
    assert first["joint"] is not None, first

    def same(a, b):  # session.json keeps float32s; the output prints them as doubles
        if isinstance(a, dict):
            return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
        if isinstance(a, list):
            return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
        return math.isclose(a, b, rel_tol=1e-6) if isinstance(a, float) else a == b

    assert same(json.loads((s / "session.json").read_text())["joint"], first["joint"])
    # The next frame is another scene: read afresh there, its joint differs.
    grasp = ",".join(map(str, first["pixel"]))
    there = json.loads(run("--json", "infer", *frame("4"), "--grasp", grasp).stdout)
    assert there["joint"] != first["joint"], there
    second = json.loads(
        run("--json", "infer", "--session", str(s), *frame("4"), "--grasp", grasp, "--moved", "true").stdout
    )
    assert second["joint"] == first["joint"], second
    state = json.loads((s / "session.json").read_text())
    state["joint"]["estimate"]["axis"] = [0.0, 0.0, 0.0]
    (s / "session.json").write_text(json.dumps(state))
    p = run("infer", "--session", str(s), *frame("4"), "--grasp", grasp, check=False)
    assert p.returncode == 2 and "session.json: joint needs a nonzero axis" in p.stderr, p.stderr


def test_a_package_with_a_joint_net_reports_the_grasped_parts_joint_from_one_frame(tmp_path, fixture_package):
    """infer's JSON carries the grasped part's joint read by the package's
    JointNet (the fixture's calls every pixel a part sliding along +x), null
    for a package without one; explore scores it against the simulator's
    joint, in JSON and in words."""
    joint_pkg = str(Path(fixture_package) / "joint")
    run("render", "--category", "Microwave", "--seed", "3", "--resolution", "96x128", "--out", str(tmp_path))
    frame = ["--rgb", str(tmp_path / "color.png"), "--depth", str(tmp_path / "depth.npy"),
             "--camera", str(tmp_path / "camera.json"), "--grasp", "48,64"]  # fmt: skip
    out = json.loads(run("--json", "infer", *frame, "--model", joint_pkg).stdout)
    assert out["joint"]["estimate"] == {"type": "prismatic", "axis": [1.0, 0.0, 0.0]}
    assert out["joint"]["voting_pixels"] > 20 and out["joint"]["hinge_probability"] < 0.01
    plain = json.loads(run("--json", "infer", *frame, "--model", str(Path(fixture_package) / "steer")).stdout)
    assert plain["joint"] is None
    # joint45: the move stays within 45 degrees of the line the joint moves the part along.
    filtered = json.loads(run("--json", "infer", *frame, "--model", joint_pkg, "--direction-filter", "joint45").stdout)
    assert abs(filtered["direction"][0]) >= math.sqrt(0.5) - 1e-6, filtered
    assert abs(plain["direction"][0]) < math.sqrt(0.5), "the filter changed the move"
    p = run(
        "infer", *frame, "--model", str(Path(fixture_package) / "steer"), "--direction-filter", "joint45", check=False
    )
    assert p.returncode == 1 and "has none (model.json `files.joint`)" in p.stderr, p.stderr
    # Laptop seed 2: the fixture's position net grasps the lid, a hinge about x.
    args = (
        "explore",
        "--category",
        "Laptop",
        "--seed",
        "2",
        "--policy",
        "umpnet",
        "--model",
        joint_pkg,
        "--steps",
        "1",
    )
    ep = json.loads(run("--json", *args).stdout)
    f = ep["frame_joint"]
    assert f["estimate"]["estimate"] == {"type": "prismatic", "axis": [1.0, 0.0, 0.0]}
    assert not f["true_prismatic"] and not f["type_right"] and f["origin_error_m"] is None
    expected = math.degrees(math.acos(min(1.0, abs(f["true_axis"][0]) / math.hypot(*f["true_axis"]))))
    assert abs(f["axis_error_deg"] - expected) < 1e-3 and expected < 10
    text = run(*args).stdout
    assert "joint from the first frame (JointNet" in text and f"{f['axis_error_deg']:.1f} deg apart" in text, text
    assert "wrong type" in text
    without = json.loads(
        run("--json", *args[:-4], "--model", str(Path(fixture_package) / "steer"), "--steps", "1").stdout
    )
    assert "frame_joint" not in without


def test_the_onward45_filter_explores_onward_along_where_the_gripper_went(tmp_path):
    """onward45 keeps the moves within 45 degrees of the gripper's own last
    motion (turned by less than that on a hinge the JointNet reads, for these
    motions) and calls them forward: from --motion in one call, from --gripper
    across a session's calls; a motion the part stopped within 2 cm says
    nothing; a goal run and a malformed motion are refused by name."""
    model = str(ROOT / "models" / "umpnet-small")
    run("render", "--category", "Microwave", "--seed", "3", "--resolution", "96x128", "--out", str(tmp_path / "f"))
    frame = ["--rgb", str(tmp_path / "f/color.png"), "--depth", str(tmp_path / "f/depth.npy"),
             "--camera", str(tmp_path / "f/camera.json"), "--model", model]  # fmt: skip
    onward = [*frame, "--direction-filter", "onward45"]

    def along(out, way):
        return sum(a * b for a, b in zip(out["direction"], way)) / math.hypot(*way)

    for way in ([0.0, 0.12, 0.0], [-0.08, 0.0, -0.06]):
        out = json.loads(
            run("--json", "infer", *onward, "--grasp", "48,64", f"--motion={','.join(map(str, way))}").stdout
        )
        assert along(out, way) >= math.sqrt(0.5) - 1e-6 and out["predicted_aot"] == 1, (way, out)
    # Where the gripper hardly went, not kept to it: joint45's rule on the
    # joint the JointNet reads at the grasp.
    joint45 = json.loads(run("--json", "infer", *frame, "--grasp", "48,64", "--direction-filter", "joint45").stdout)
    small = json.loads(run("--json", "infer", *onward, "--grasp", "48,64", "--motion=0,0.01,0").stdout)
    assert small["joint"] is not None and small["direction"] == joint45["direction"], (small, joint45)
    # A session reads the motion from where --gripper says the gripper went.
    s = str(tmp_path / "session")
    first = json.loads(run("--json", "infer", "--session", s, *onward).stdout)
    went = [0.0, 0.1, 0.05]
    gripper = ",".join(f"{p + d:.5f}" for p, d in zip(first["point_in_world"], went))
    second = json.loads(
        run("--json", "infer", "--session", s, *onward, f"--gripper={gripper}", "--moved", "true").stdout
    )
    assert along(second, went) >= math.sqrt(0.5) - 1e-6 and second["predicted_aot"] == 1, second

    def long_motion():
        return json.loads((tmp_path / "session" / "session.json").read_text())["long_motion"]

    assert all(abs(a - b) < 1e-4 for a, b in zip(long_motion(), went)), long_motion()
    # A move that stalled: the session keeps the last long motion (goal45 reads it).
    run("--json", "infer", "--session", s, *onward, f"--gripper={gripper}", "--moved", "false")
    assert all(abs(a - b) < 1e-4 for a, b in zip(long_motion(), went)), long_motion()
    for extra, code, says in [
        (["--grasp", "48,64", "--motion", "1,2"], 2, "--motion takes x,y,z"),
        (["--grasp", "48,64", "--reference", str(tmp_path / "f/color.png"), "--reference-depth",
          str(tmp_path / "f/depth.npy")], 1, "onward45 direction filter serves exploration only"),
    ]:  # fmt: skip
        p = run("infer", *onward, *extra, check=False)
        assert p.returncode == code and says in p.stderr, (extra, p.stderr)
