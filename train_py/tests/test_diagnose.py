"""`umpnet_train.diagnose`: the heads are scored only where no filter rewrote
them, the policy-as-run mode feeds each policy its episode (a move that moved
nothing is not tried again), the figures are those of the moves made, its
measures are right on known values, and `train --eval-every` logs them."""

import numpy as np
import pytest
import umpnet
from umpnet_train import diagnose, fixture, train
from umpnet_train.export import export_model


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    # The decoder ignores the image and steers exploration along +x (fixture.steering_model).
    model, cfg = fixture.steering_model()
    path = tmp_path_factory.mktemp("diagnose") / "pkg"
    export_model(model, cfg, path, {"command": "test_diagnose", "trained": False})
    return path


class Recording(diagnose.Episodes):
    """Episodes that keep, per environment, each decision and what the move did."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.trace = []

    def decide(self, obs, live, mode, moved, gripper):
        out = super().decide(obs, live, mode, moved, gripper)
        self.trace.append((live.copy(), None if moved is None else moved.copy(), [r["direction"] for r in out]))
        return out


def test_the_heads_are_scored_only_where_no_filter_rewrote_them(package):
    policy = umpnet.Policy(str(package), seed=0)
    plain = diagnose.run(policy, "train", "exploration", 2, 11, "reference", position="oracle", n=2).summary()
    assert 0.0 <= plain["aot_accuracy"] <= 1.0 and plain["states"] > 0
    lo, hi = plain["aot_accuracy_95"]
    assert lo <= plain["aot_accuracy"] <= hi
    confusion = np.array(plain["aot_confusion"])
    assert confusion.shape == (3, 3)
    assert plain["aot_accuracy"] == pytest.approx(np.trace(confusion) / confusion.sum())
    seen = confusion.sum(1) > 0
    recalls = np.diag(confusion)[seen] / confusion.sum(1)[seen]
    assert plain["aot_balanced_accuracy"] == pytest.approx(recalls.mean())
    # Per category: the episodes and the candidates split the run's, and a
    # category's figures are its own episodes' (one category alone is the run).
    by = plain["by_category"]
    assert sum(f["episodes"] for f in by.values()) == plain["episodes"] == 2
    assert np.array_equal(sum(np.array(f["aot_confusion"] or np.zeros((3, 3))) for f in by.values()), confusion)
    alone = diagnose.run(policy, "train", "exploration", 1, 11, "reference", position="oracle", n=2).summary()
    first = next(iter(by))
    assert list(alone["by_category"]) == [first]
    assert alone["by_category"][first] == {
        k: v for k, v in alone.items() if k not in ("by_category", "rank_correlation", "states")
    }
    # The chosen direction is one of the probed ones: never more progress than the best.
    assert plain["progress_share"] is None or plain["progress_share"] <= 1.0 + 1e-9
    memory = diagnose.Episodes(package, 2, 11, "none")
    ran = diagnose.run(policy, "train", "exploration", 2, 11, "reference", position="oracle", n=2, memory=memory)
    ran = ran.summary()
    assert ran["aot_accuracy"] is None and ran["rank_correlation"] is None and ran["states"] > 0
    assert ran["progress_share"] is None or ran["progress_share"] <= 1.0 + 1e-9


def test_a_move_that_moved_nothing_is_not_made_again_within_the_episode(package):
    policy = umpnet.Policy(str(package), seed=0)
    memory = Recording(package, 2, 5, "none")
    diagnose.run(policy, "train", "exploration", 2, 5, "reference", position="oracle", n=2, probe=False, memory=memory)
    stalls = 0
    for (_, _, before), (live, moved, after) in zip(memory.trace, memory.trace[1:], strict=False):
        for i in np.flatnonzero(live):
            if before[i] is not None and after[i] is not None and not moved[i]:
                stalls += 1
                # The runtime bans a cone of about 20 degrees about a move that stalled (cem.rs BAN_COS).
                assert np.dot(before[i], after[i]) <= 0.94, (before[i], after[i])
    # Steered along +x whatever it sees, the policy stalls on most parts: the check above ran.
    assert stalls > 0


def test_the_same_seed_gives_the_same_report(package):
    def once():
        policy = umpnet.Policy(str(package), seed=0)
        memory = diagnose.Episodes(package, 2, 3, "onward45")
        return diagnose.run(policy, "train", "exploration", 3, 3, "reference", n=2, memory=memory).summary()

    assert once() == once()


def test_a_filter_that_does_not_serve_the_task_is_refused_by_name(package, capsys):
    for flag, name in (("--explore-filter", "goal45"), ("--goal-filter", "onward45")):
        with pytest.raises(SystemExit) as e:
            diagnose.main([str(package), flag, name])
        assert e.value.code == 2
        assert flag in capsys.readouterr().err


def test_categories_limit_the_run_and_a_split_without_them_is_left_out(package, capsys):
    report = diagnose.diagnose(package, 2, 0, "reference", categories=["Door"])
    assert report["categories"] == ["Door"] and list(report["splits"]) == ["test"]
    for task in ("exploration", "goal"):
        figures = report["splits"]["test"][task]
        assert list(figures["by_category"]) == ["Door"] and figures["episodes"] == 2
    both = diagnose.diagnose(package, 2, 0, "reference", categories=["Door", "Laptop"])
    assert list(both["splits"]) == ["train", "test"]
    assert list(both["splits"]["train"]["goal"]["by_category"]) == ["Laptop"]
    with pytest.raises(ValueError, match="'Dor'"):
        diagnose.diagnose(package, 2, 0, "reference", categories=["Dor"])
    with pytest.raises(SystemExit) as e:
        diagnose.main([str(package), "--categories", "Door,Dor"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "--categories" in err and "'Dor'" in err and "Laptop" in err


def test_diagnostic_measures_on_known_values():
    assert diagnose.spearman(np.array([1.0, 2, 3]), np.array([10.0, 20, 30])) == pytest.approx(1.0)
    assert diagnose.spearman(np.array([1.0, 2, 3]), np.array([3.0, 2, 1])) == pytest.approx(-1.0)
    assert diagnose.spearman(np.array([1.0, 2, 3]), np.array([5.0, 5, 5])) is None
    # Toward the reference is -1, away +1, not moved 0.
    aot = diagnose.true_aot(0.5, np.array([0.3, 0.8, 0.5]), 0.0, np.array([True, True, False]))
    np.testing.assert_array_equal(aot, [-1, 1, 0])
    # Progress: away from the start when exploring, toward the goal otherwise.
    np.testing.assert_allclose(diagnose.progress(0.5, np.array([0.8, 0.2]), 0.0, 1.0, "exploration"), [0.3, -0.3])
    np.testing.assert_allclose(diagnose.progress(0.5, np.array([0.8, 0.2]), 0.0, 1.0, "goal"), [0.3, -0.3])
    np.testing.assert_allclose(diagnose.progress(0.5, np.array([0.8, 0.2]), 0.0, 0.0, "goal"), [-0.3, 0.3])


def test_periodic_evaluation_logs_the_diagnostics(tmp_path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    out = tmp_path / "run"
    assert train.main(["--preset", "smoke", "--out", str(out), "--epochs", "1", "--eval-every", "1"]) == 0
    tags = EventAccumulator(str(out / "tb")).Reload().Tags()["scalars"]
    for tag in (
        "diagnose/test/goal/aot_accuracy",
        "diagnose/train/exploration/position_validity",
        "diagnose/test/goal_success/learned/oracle",
    ):
        assert tag in tags, sorted(tags)
    assert any(t.startswith("eval/goal/") for t in tags), sorted(tags)
