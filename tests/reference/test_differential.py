"""umpnet's `reference` physics against the paper's simulator (PyBullet), on
the same URDFs, grasp points and scripted directions (differential.py)."""

import os
from pathlib import Path

import differential as D
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
UMPNET = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))


@pytest.fixture(scope="module")
def cabinet(tmp_path_factory):
    cases = D.cabinet_cases(tmp_path_factory.mktemp("cabinet"))
    return {c.name: D.run_case(c) for c in cases}


@pytest.fixture(scope="module")
def families(tmp_path_factory):
    cases = D.generated_cases(UMPNET, tmp_path_factory.mktemp("objects"), per_category=2)
    return [D.run_case(c) for c in cases]


def _print(results):
    print()
    print(D.table(results))


def test_cabinet_trajectories_match_pybullet(cabinet):
    _print(cabinet.values())
    for r in cabinet.values():
        mean, worst = D.BOUNDS[r.case.kind]
        assert r.deviation.mean() <= mean and r.deviation.max() <= worst, D.table([r])


def test_the_reference_behaviours_hold_in_both(cabinet):
    # A free drawer moves about 0.13 m per 0.18 m action, and loses nothing after its limit.
    drawer = cabinet["drawer, 5 pulls then 5 pushes"]
    for values in (drawer.reference, drawer.umpnet):
        assert values[0] == pytest.approx(0.13, abs=0.005)
        assert values[5] - values[4] == pytest.approx(-0.13, abs=0.005)
    # A pull along -y across the door's arc stalls well before the limit.
    door = cabinet["door, pull along -y"]
    for values in (door.reference, door.umpnet):
        assert values[-1] < 1.0 and values[-1] - values[-4] < 0.01
    # Along the tangent the same door opens to its limit.
    tangent = cabinet["door, pull along its tangent"]
    assert min(tangent.reference[-1], tangent.umpnet[-1]) > 1.5
    # A grasp 5 cm from the hinge cannot turn the door.
    near = cabinet["door, grasp 5 cm from the hinge"]
    assert max(np.abs(near.reference).max(), np.abs(near.umpnet).max()) < 0.02


def test_every_generated_family_matches_pybullet_under_random_directions(families):
    _print(families)
    categories = {r.case.name.split("/")[0] for r in families}
    assert len(categories) == 22
    summary = D.summarize(families)
    print(summary)
    for kind, (mean, worst) in D.BOUNDS.items():
        assert summary[kind]["mean"] <= mean, summary
        assert summary[kind]["max"] <= worst, summary
    # The suite exercises real motion, not only stalls.
    moved = np.concatenate([np.abs(np.diff(r.reference)) for r in families])
    assert (moved > 0.1).sum() > 50
