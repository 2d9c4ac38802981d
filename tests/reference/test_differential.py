"""umpnet's `reference` physics against the paper's simulator (PyBullet), on
the same URDFs, grasp points and scripted directions (differential.py)."""

import os
import subprocess
import sys
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


# Objects made by others (Meta-World, through MuJoCo), and an MJCF cabinet
# with two doors and a drawer: a hinge, a slide, and several joints in one file.
IMPORTED = ["drawer", "laptop", "faucet", "lever", "window", "doorlockA", "thermos", "two_door_cabinet"]


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    out = tmp_path_factory.mktemp("imported")
    importer = [sys.executable, "-m", "umpnet.objects"]
    subprocess.run([*importer, "metaworld", "--out", str(out)], check=True, capture_output=True)
    cabinet = ROOT / "tests" / "data" / "mjcf" / "two_door_cabinet.xml"
    subprocess.run([*importer, "import-mjcf", str(cabinet), "--out", str(out)], check=True, capture_output=True)
    cases = D.folder_cases([out / name / "mobility.urdf" for name in IMPORTED], actions=8)
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


def test_imported_mjcf_objects_match_pybullet_at_their_scene_scale(imported):
    _print(imported)
    objects = {r.case.name.split("/")[1].split()[0] for r in imported}
    assert objects == set(IMPORTED)
    kinds = {r.case.kind for r in imported}
    assert kinds == {"revolute", "prismatic"}
    several = [r for r in imported if "/two_door_cabinet " in r.case.name]
    assert len(several) == 3, [r.case.name for r in several]
    for r in imported:
        # Imported objects are tested at the scale their object_meta_info.json gives.
        assert r.case.scale != 1.0
        mean, worst = D.BOUNDS[r.case.kind]
        assert r.deviation.mean() <= mean and r.deviation.max() <= worst, D.table([r])
    moved = np.concatenate([np.abs(np.diff(r.reference)) for r in imported])
    assert (moved > 0.05).sum() > 10
