"""JointNet: its labels against the simulator's fields, a short run that
learns, resumes and exports, and the runtime reading the export."""

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import torch
import umpnet
from umpnet_train import frame_joint, joint_net

SMALL = joint_net.JointConfig(height=48, width=64, widths=(4, 8), frames=16, steps=4, batch=4, seed=3)


def test_labels_agree_with_the_simulators_flow_and_speed():
    """On a hinge, each point's vector to the axis is as long as its speed
    says (relative to the part's fastest point) and turning about the axis
    moves it along the flow; on a slide the axis is the flow."""
    rng = np.random.default_rng(0)
    kinds = set()
    for category in ("Refrigerator", "StorageFurniture", "Laptop", "Window"):
        env = umpnet.Env(category, seed=1, split="train", copy=True, resolution=(96, 128))
        _image, labels = joint_net.frame(env, rng, 0)
        fields = env.articulation_fields()
        assert (labels["movable"] == (fields["joint"] >= 0)).all()
        for j in np.unique(fields["joint"][fields["joint"] >= 0]):
            on = fields["joint"] == j
            kind = labels["kind"][on]
            assert (kind == kind[0]).all()
            kinds.add(int(kind[0]))
            flow, axis = fields["flow"][on], labels["axis"][on]
            moving = np.linalg.norm(flow, axis=1) > 0.5
            if kind[0] == 1:
                reach = np.linalg.norm(labels["to_axis"][on], axis=1)
                np.testing.assert_allclose(reach / reach.max(), fields["speed"][on], atol=2e-3)
                turn = np.cross(axis, -labels["to_axis"][on])[moving]
                cos = np.sum(turn * flow[moving], axis=1) / np.linalg.norm(turn, axis=1)
                assert np.abs(cos).min() > 0.999
            elif kind[0] == 0:
                assert np.abs(np.sum(axis * flow, axis=1)).min() > 0.999
                assert (labels["to_axis"][on] == 0).all()
    assert kinds == {0, 1}, "both kinds of joint are seen"


def test_a_short_run_learns_resumes_exports_and_the_runtime_reads_it(tmp_path, fixture_package):
    data = joint_net.make_dataset(SMALL)
    again = joint_net.make_dataset(SMALL)
    assert all(np.array_equal(data[k], again[k]) for k in data), "the same seed gives the same frames"
    batch = {k: torch.from_numpy(v.astype(np.float32) if v.dtype == np.float16 else v) for k, v in data.items()}
    batch["kind"] = batch["kind"].long()

    def joint_loss(model):
        # The joint's own terms (flow, axis, the way to the axis) on the frames it learns from.
        model.eval()
        with torch.no_grad():
            losses = joint_net.joint_losses(model(batch["image"]), batch)
        return sum(losses[k].item() for k in ("flow", "axis", "to_axis"))

    torch.manual_seed(SMALL.seed)
    before = joint_loss(joint_net.JointNet(SMALL))
    model = joint_net.train(dataclasses.replace(SMALL, steps=200), tmp_path / "learn", resume=False)
    assert joint_loss(model) < 0.5 * before

    run = tmp_path / "run"
    run.mkdir()
    joint_net.train(SMALL, run, resume=False)
    assert torch.load(run / "joint.pt", weights_only=False)["step"] == 4
    joint_net.train(dataclasses.replace(SMALL, steps=6), run, resume=True)
    assert torch.load(run / "joint.pt", weights_only=False)["step"] == 6

    package = tmp_path / "package"
    shutil.copytree(
        Path(fixture_package), package, ignore=shutil.ignore_patterns("steer*", "inverse", "joint", "reference")
    )
    joint_net.export(run / "joint.pt", package)
    policy = umpnet.Policy(str(package))
    env = umpnet.Env("Laptop", seed=2, split="test", copy=True, resolution=policy.resolution)
    image = env.reset()["image"]
    model, _ = joint_net.load(run / "joint.pt")
    with torch.no_grad():
        fields = model(torch.from_numpy(image[None]))[0].numpy()
    pixel = tuple(int(v) for v in env.scripted_action("oracle"))
    assert policy.frame_joint(image, pixel) == umpnet._umpnet.joint_from_fields(image, fields, pixel)
    report = frame_joint.measure(run / "joint.pt", "test", 1)
    assert report["all"]["n"] > 0 and report["by_true_type"]["revolute"]["n"] > 0
    assert frame_joint.measure(package, "test", 1)["all"]["n"] == report["all"]["n"]
    # Objects made elsewhere: an MJCF cabinet imported as an object folder.
    from umpnet.objects import import_mjcf

    objects = tmp_path / "objects"
    import_mjcf(Path(__file__).resolve().parents[2] / "tests/data/mjcf/two_door_cabinet.xml", objects)
    on_objects = frame_joint.measure(package, "test", 2, objects=objects)
    assert list(on_objects["by_category"]) == ["two_door_cabinet"] and on_objects["all"]["n"] == 2
    assert sum(t["n"] for t in on_objects["by_true_type"].values()) == 2


def test_worker_processes_make_the_same_frames_as_one():
    cfg = dataclasses.replace(SMALL, frames=10)
    alone = joint_net.make_dataset(cfg, workers=1, size=4)
    shared = joint_net.make_dataset(cfg, workers=2, size=4)
    assert all(np.array_equal(alone[k], shared[k]) for k in alone)
    assert len({alone["image"][i].tobytes() for i in range(10)}) == 10, "every frame its own"


def test_a_time_limit_stops_with_a_checkpoint_that_resumes(tmp_path):
    joint_net.train(dataclasses.replace(SMALL, steps=50), tmp_path, resume=False, time_limit=1e-9)
    assert torch.load(tmp_path / "joint.pt", weights_only=False)["step"] == 1
    joint_net.train(dataclasses.replace(SMALL, steps=3), tmp_path, resume=True)
    ck = torch.load(tmp_path / "joint.pt", weights_only=False)
    assert ck["step"] == 3 and ck["device"] == "cpu"
    # A shipped checkpoint keeps its weights alone: a resume starts Adam afresh from them.
    del ck["optimizer"]
    torch.save(ck, tmp_path / "joint.pt")
    model = joint_net.train(dataclasses.replace(SMALL, steps=4), tmp_path, resume=True)
    assert torch.load(tmp_path / "joint.pt", weights_only=False)["step"] == 4
    assert not torch.equal(model.state_dict()["unet.head.weight"], ck["model"]["unet.head.weight"])


def test_color_jitter_changes_colours_alone_and_keeps_them_in_range():
    image = torch.rand(8, 6, 7, 10)
    before = image.clone()
    joint_net.jitter_colors(image, np.random.default_rng(0))
    assert torch.equal(image[..., :3], before[..., :3]) and torch.equal(image[..., 6:], before[..., 6:])
    rgb = image[..., 3:6]
    assert rgb.min() >= 0 and rgb.max() <= 1 and not torch.allclose(rgb, before[..., 3:6])
    grey = (rgb[..., 0] == rgb[..., 1]).all(dim=(1, 2))
    assert 0 < int(grey.sum()) < 8, "some images grey, not all"


def test_a_mirrored_frame_carries_the_labels_of_the_mirrored_scene():
    """`--mirror` relabels a frame without the simulator: its labels must be
    the ones the simulator's own fields give once mirrored (points and flow
    with x negated, columns reversed), for hinges and slides alike."""
    rng = np.random.default_rng(0)
    frames, fits = [], []
    for category, seed in (("Refrigerator", 2), ("StorageFurniture", 3), ("Window", 5)):
        env = umpnet.Env(category, seed=seed, split="train", copy=True, resolution=(48, 64))
        image, labels = joint_net.frame(env, rng, 0)
        fields = env.articulation_fields()
        image_m = umpnet._umpnet.mirrored_observations(image[None].astype(np.float32))[0]
        fields_m = {k: fields[k][:, ::-1].copy() for k in ("joint", "speed", "flow")}
        fields_m["flow"][..., 0] *= -1
        frames.append((image, labels))
        fits.append((image_m, joint_net.joint_labels(image_m, fields_m)))
    batch = {k: torch.from_numpy(np.stack([f[1][k] for f in frames])) for k in frames[0][1]}
    batch["image"] = torch.from_numpy(np.stack([f[0] for f in frames]).astype(np.float32))
    before = {k: v.clone() for k, v in batch.items()}
    joint_net.mirror_frames(batch, np.array([0, 2]))
    assert all(torch.equal(batch[k][1], before[k][1]) for k in batch), "a frame not chosen is kept"
    kinds = set()
    for i in (0, 2):
        image_m, expected = fits[i]
        np.testing.assert_array_equal(batch["image"][i].numpy(), image_m)
        for k in ("movable", "kind"):
            np.testing.assert_array_equal(batch[k][i].numpy(), expected[k])
        np.testing.assert_allclose(batch["flow"][i].numpy(), expected["flow"], atol=1e-5)
        np.testing.assert_allclose(batch["to_axis"][i].numpy(), expected["to_axis"], atol=1e-4)
        on = expected["kind"] >= 0
        kinds |= set(np.unique(expected["kind"][on]).tolist())
        # An axis is a line: the fit may give either sign.
        cos = np.sum(batch["axis"][i].numpy()[on] * expected["axis"][on], axis=-1)
        assert np.abs(cos).min() > 0.999
    assert kinds == {0, 1}, "a hinge and a slide are mirrored"


def test_export_refuses_a_package_of_another_size(tmp_path, fixture_package):
    run = tmp_path / "run"
    run.mkdir()
    joint_net.train(dataclasses.replace(SMALL, height=24, width=32, frames=4, steps=1), run, resume=False)
    package = tmp_path / "package"
    shutil.copytree(
        Path(fixture_package), package, ignore=shutil.ignore_patterns("steer*", "inverse", "joint", "reference")
    )
    try:
        joint_net.export(run / "joint.pt", package)
    except ValueError as e:
        assert "input 48x64, JointNet 24x32" in str(e)
    else:
        raise AssertionError("exported a 24x32 JointNet into a 48x64 package")
    assert "joint" not in (package / "model.json").read_text().split('"files"')[1].split("}")[0]


def test_the_command_refuses_bad_flags_by_name(tmp_path, capsys):
    for flags, named in (
        (["--mirror", "1.5"], "--mirror 1.5"),
        (["--widths", "16,x"], "--widths 16,x"),
        (["--frames", "2", "--batch", "4"], "--frames"),
        (["--device", "tpu"], "--device tpu"),
    ):
        try:
            joint_net.main(["--out", str(tmp_path / "run"), *flags])
        except SystemExit as e:
            assert e.code == 2
        else:
            raise AssertionError(f"{flags} accepted")
        assert named in capsys.readouterr().err
    assert not (tmp_path / "run").exists(), "nothing is trained or written"
