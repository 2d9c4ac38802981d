"""Collection on Ray actors (`train --ray N`): what actors record is what a
local run would have added, and a run on a local cluster of 2 actors trains,
checkpoints and depends only on its seed."""

import re

import numpy as np
import pytest
import torch
import umpnet
from umpnet_train import collect, train
from umpnet_train.config import make_config
from umpnet_train.distributed import Recorder, merge_stats, new_stats, replay_into, split_envs
from umpnet_train.models import UMPNet
from umpnet_train.replay import DenseReplay, Replay


def _buffers(cfg):
    shape = (cfg.height, cfg.width, 10)
    return Replay(cfg.replay_size, shape), DenseReplay(cfg.replay_size // 4, shape, cfg.dense_labels)


def _collect(cfg, replay, dense, seed=5):
    torch.manual_seed(0)
    model = UMPNet(cfg)
    env = umpnet.VecEnv(6, category=["Microwave", "Refrigerator", "StorageFurniture"], split="train", seed=seed,
                        resolution=(cfg.height, cfg.width), renderer="cpu")  # fmt: skip
    stats = new_stats()
    collect.collect(env, model, cfg, replay, dense, 0, np.random.default_rng(seed), stats)
    return stats


def test_recorded_collection_replays_into_the_same_buffers():
    cfg = make_config("smoke", dense_labels=4, renderer="cpu")
    direct, direct_dense = _buffers(cfg)
    stats_direct = _collect(cfg, direct, direct_dense)
    recorder = Recorder()
    stats_recorded = _collect(cfg, recorder, recorder)
    replayed, replayed_dense = _buffers(cfg)
    replay_into(recorder.ops, replayed, replayed_dense)
    assert stats_direct["steps"] > 0 and stats_direct["dense_labels"] > 0
    assert stats_direct["steps"] == stats_recorded["steps"]
    for name, arr in direct.arrays().items():
        other = replayed.arrays()[name]
        # Images travel as float16, as the buffer stores them: equal, not close.
        assert np.array_equal(arr, other), name
    for name in ("images", "pixels", "vectors", "dist", "aot", "ref", "ref_gen"):
        assert np.array_equal(getattr(direct_dense, name), getattr(replayed_dense, name)), name
    assert direct.refs.count == replayed.refs.count and direct.dir.count == replayed.dir.count


def test_environments_split_evenly_and_stats_add_up():
    assert split_envs(16, 3) == [6, 5, 5] and sum(split_envs(7, 7)) == 7
    with pytest.raises(ValueError, match="--ray 5"):
        split_envs(4, 5)
    total, part = new_stats(), new_stats()
    part["steps"], part["aot_counts"] = 3, [1, 1, 1]
    merge_stats(total, part)
    merge_stats(total, part)
    assert total["steps"] == 6 and total["aot_counts"] == [2, 2, 2]


def test_smoke_training_on_two_local_ray_actors_depends_only_on_the_seed(tmp_path, capsys):
    import ray

    weights = []
    try:
        for run in ("a", "b"):
            out = tmp_path / run
            args = ["--preset", "smoke", "--out", str(out), "--epochs", "2", "--ray", "2", "--dense-labels", "4"]
            assert train.main([*args, "--renderer", "cpu"]) == 0
            text = capsys.readouterr().out
            found = re.search(r"collection \(2 Ray actors\): (\d+) direction samples", text)
            assert found and int(found.group(1)) > 0, text
            ck = torch.load(out / "checkpoint.pt", weights_only=False)
            assert ck["epoch"] == 2 and ck["provenance"]["collection"] == "ray, 2 actors"
            weights.append(ck["model"])
    finally:
        ray.shutdown()
    assert weights[0].keys() == weights[1].keys()
    for k in weights[0]:
        assert torch.equal(weights[0][k], weights[1][k]), k
    assert train.main(["--preset", "smoke", "--out", str(tmp_path / "c"), "--ray", "9"]) == 2
    assert "--ray 9" in capsys.readouterr().err
