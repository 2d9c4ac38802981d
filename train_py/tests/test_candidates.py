"""`umpnet_train.candidates`: the labels are those of the candidates the
package's policy scores, collected the same way from the same seed, and
fine-tuning on them raises held-out accuracy without touching the position net."""

import dataclasses

import numpy as np
import pytest
import torch
from umpnet_train import candidates, fixture
from umpnet_train.export import export_model


@pytest.fixture(scope="module")
def steering(tmp_path_factory):
    # The decoder ignores the image and calls every +x move forward (fixture.steering_model).
    model, cfg = fixture.steering_model()
    root = tmp_path_factory.mktemp("candidates")
    export_model(model, cfg, root / "pkg", {"command": "test_candidates", "trained": False})
    torch.save({"config": dataclasses.asdict(cfg), "model": model.state_dict()}, root / "checkpoint.pt")
    return root


@pytest.fixture(scope="module")
def data(steering):
    return candidates.collect(steering / "pkg", episodes=4, seed=2, n=4, log=lambda *_: None)


def test_every_state_carries_its_candidates_labels(data):
    states = len(data["mode"])
    assert states > 0 and set(np.unique(data["mode"])) == {0, 1}  # both tasks
    real = data["aot"] != 2
    assert real.any(axis=1).all()
    assert np.isfinite(data["candidates"][real]).all() and np.isnan(data["candidates"][~real]).all()
    assert np.allclose(np.linalg.norm(data["candidates"][real], axis=1), 1.0, atol=1e-4)
    assert set(np.unique(data["aot"][real])) <= {-1, 0, 1}
    assert (data["dist"][real] >= 0).all() and (data["dist"][~real] == 0).all()
    h, w = data["image"].shape[1:3]
    assert ((data["pixel"] >= 0) & (data["pixel"] < [h, w])).all()
    # A candidate labelled as moving the part moved it further than any labelled still.
    moved = real & (data["aot"] != 0)
    if moved.any() and (real & ~moved).any():
        assert data["dist"][real & ~moved].max() < data["dist"][moved].min() + 1e-6


def test_the_same_seed_collects_the_same_labels(steering, data):
    again = candidates.collect(steering / "pkg", episodes=4, seed=2, n=4, log=lambda *_: None)
    for k in data:
        assert np.array_equal(data[k], again[k], equal_nan=True), k


def test_fine_tuning_raises_held_out_accuracy_and_leaves_the_position_net(steering, data, tmp_path):
    settings = candidates.Settings(steps=60, batch_states=4, lr=1e-2, threads=1)
    path = candidates.finetune(steering / "checkpoint.pt", data, tmp_path / "run", settings, log=lambda *_: None)
    ck = torch.load(path, map_location="cpu", weights_only=False)
    acc = ck["provenance"]["segments"][-1]["held_out_aot_accuracy"]
    # The steering decoder calls half the sphere forward; most candidates move nothing.
    assert acc["after"] > acc["before"] + 0.05
    before = torch.load(steering / "checkpoint.pt", map_location="cpu", weights_only=False)["model"]
    for k, v in ck["model"].items():
        if k.startswith("position."):
            assert torch.equal(v, before[k]), k
    assert any(not torch.equal(v, before[k]) for k, v in ck["model"].items() if k.startswith("decoder."))
    candidates.export_package(path, steering / "pkg", tmp_path / "pkg")
    assert (tmp_path / "pkg" / "model.json").is_file()


def test_a_mirrored_state_is_the_same_scene_seen_in_a_mirror(data):
    which = np.arange(0, len(data["mode"]), 2)
    m = candidates.mirrored(data, which)
    w = data["image"].shape[2]
    for i in range(len(data["mode"])):
        if i % 2:  # states not chosen are untouched
            assert all(np.array_equal(m[k][i], data[k][i], equal_nan=True) for k in data), i
            continue
        (r, c), (rm, cm) = data["pixel"][i], m["pixel"][i]
        assert rm == r and cm == w - 1 - c
        for key in ("image", "reference"):
            was, now = data[key][i, r, c].astype(np.float32), m[key][i, rm, cm].astype(np.float32)
            assert np.allclose(now[[0, 6]], -was[[0, 6]]) and np.allclose(
                np.delete(now, [0, 6]), np.delete(was, [0, 6])
            )
        # Each candidate keeps its angle to the grasped surface's normal.
        real = data["aot"][i] != 2
        normal, normal_m = data["image"][i, r, c, 6:9].astype(np.float32), m["image"][i, rm, cm, 6:9].astype(np.float32)
        assert np.allclose(data["candidates"][i, real] @ normal, m["candidates"][i, real] @ normal_m, atol=1e-3)
    for key in ("aot", "dist", "mode"):
        assert np.array_equal(m[key], data[key])
    again = candidates.mirrored(m, which)
    assert all(np.array_equal(again[k], data[k], equal_nan=True) for k in data)


def test_a_last_partial_batch_records_only_the_episodes_asked_for(steering, data):
    # Two episodes of four environments: the third and fourth run (so the
    # others see the same scenes and decisions) but none of their states is kept.
    fewer = candidates.collect(steering / "pkg", episodes=2, seed=2, n=4, log=lambda *_: None)
    assert 0 < len(fewer["mode"]) < len(data["mode"])
    kept = {data["image"][i].tobytes() + data["candidates"][i].tobytes() for i in range(len(data["mode"]))}
    assert all(
        fewer["image"][i].tobytes() + fewer["candidates"][i].tobytes() in kept for i in range(len(fewer["mode"]))
    )


def test_another_dataset_seed_collects_other_instances(steering, data, tmp_path, capsys):
    # The same scene seeds on another generated dataset: the same families,
    # other instances, so no state's image is one of dataset 0's.
    other = candidates.collect(steering / "pkg", episodes=4, seed=2, n=4, dataset_seed=1, log=lambda *_: None)
    assert len(other["mode"]) > 0
    seen = {data["image"][i].tobytes() for i in range(len(data["mode"]))}
    assert not any(other["image"][i].tobytes() in seen for i in range(len(other["mode"])))
    with pytest.raises(SystemExit):
        candidates.main(["collect", str(steering / "pkg"), str(tmp_path / "x.npz"), "--dataset-seed", "-1"])
    assert "--dataset-seed" in capsys.readouterr().err
    assert not (tmp_path / "x.npz").exists()


def test_a_zero_still_weight_scores_only_the_candidates_that_move(steering, data):
    ck = torch.load(steering / "checkpoint.pt", map_location="cpu", weights_only=False)
    model, _ = fixture.steering_model()
    model.load_state_dict(ck["model"])
    model.eval()
    moving = data["aot"].copy()
    moving[moving == 0] = 2  # still candidates marked as padding
    assert (moving != 2).any() and (data["aot"] == 0).any()
    with torch.no_grad():
        weighted = candidates.candidate_losses(model, data, 100.0, still_weight=0.0)["loss/aot"]
        only_moving = candidates.candidate_losses(model, {**data, "aot": moving}, 100.0)["loss/aot"]
        natural = candidates.candidate_losses(model, data, 100.0)["loss/aot"]
    assert torch.isclose(weighted, only_moving, rtol=1e-5) and not torch.isclose(weighted, natural, rtol=1e-3)


def test_files_with_different_candidate_counts_merge_padded(data):
    narrow = {k: v[:, :3] if k in ("candidates", "aot", "dist") else v for k, v in data.items()}
    merged = candidates.merge([narrow, data])
    states, k = len(data["mode"]) * 2, data["candidates"].shape[1]
    assert merged["candidates"].shape == (states, k, 3) and merged["aot"].shape == (states, k)
    half = len(data["mode"])
    assert np.isnan(merged["candidates"][:half, 3:]).all() and (merged["aot"][:half, 3:] == 2).all()
    assert np.array_equal(merged["aot"][half:], data["aot"]) and (merged["dist"][:half, 3:] == 0).all()


def test_bad_input_is_refused_by_name(tmp_path, capsys):
    with pytest.raises(SystemExit):
        candidates.main(["collect", str(tmp_path), str(tmp_path / "x.npz")])
    assert "not a model package" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        candidates.main(["finetune", str(tmp_path / "missing.pt"), str(tmp_path / "d.npz"), str(tmp_path / "run")])
    assert "missing.pt: no such file" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        candidates.main(
            ["finetune", str(tmp_path / "c.pt"), str(tmp_path / "d.npz"), str(tmp_path / "r"), "--still-weight", "0"]
        )
    assert "--still-weight" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        candidates.main(
            ["finetune", str(tmp_path / "c.pt"), str(tmp_path / "d.npz"), str(tmp_path / "r"), "--mirror", "2"]
        )
    assert "--mirror within [0, 1]" in capsys.readouterr().err


def test_categories_narrow_the_collection_and_refuse_test_categories(steering, data, tmp_path, capsys):
    # The same scene seeds on one category: were the option ignored, the
    # states would be the fixture's (all twelve categories) exactly.
    kettles = candidates.collect(steering / "pkg", episodes=4, seed=2, n=4, categories=["Kettle"], log=lambda *_: None)
    assert len(kettles["mode"]) > 0
    seen = {data["image"][i].tobytes() for i in range(len(data["mode"]))}
    assert not all(kettles["image"][i].tobytes() in seen for i in range(len(kettles["mode"])))
    for bad, named in {"Oven": "Oven", "Kettle,Spaceship": "Spaceship", ",": "(empty)"}.items():
        with pytest.raises(SystemExit):
            candidates.main(["collect", str(steering / "pkg"), str(tmp_path / "x.npz"), "--categories", bad])
        err = capsys.readouterr().err
        assert f"--categories {named}: expected training categories" in err, err
    assert not (tmp_path / "x.npz").exists()
