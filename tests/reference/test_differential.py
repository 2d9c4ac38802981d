"""umpnet's `reference` physics against the paper's simulator (PyBullet), on
the same URDFs, grasp points and scripted directions (differential.py)."""

import os
import subprocess
import sys
from dataclasses import dataclass
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


# Bounds sit at about 2.5x the deviations measured when they were set (both
# simulators are deterministic; `differential.py` prints the measured values),
# so a regression of a few times fails. Rad for hinges, m for slides; link
# points in m. A joint that neither simulator moves is held to OTHER_JOINTS.
OTHER_JOINTS = 0.0005
# Per case: grasped joint's mean and max |d|, link points' max distance.
CABINET = {
    "door, pull along -y": (0.0014, 0.0016, 0.0007),
    "door, pull along its tangent": (0.0014, 0.0027, 0.0011),
    "drawer, 5 pulls then 5 pushes": (0.0002, 0.0005, 0.0005),
    "door, grasp 5 cm from the hinge": (0.00025, 0.00025, 0.0001),
    "lid lifted (no <inertial>)": (0.0004, 0.0015, 0.0008),
    "door, yawed 30 deg and scaled 0.55, along its tangent": (0.003, 0.0056, 0.0013),
}


@dataclass(frozen=True)
class KindBounds:
    mean: float  # over every action of the kind in the group
    case_mean: float  # the largest mean of one case
    max: float  # the largest single action
    links: float  # link points, m
    other_joints: float = OTHER_JOINTS


FAMILIES = {
    "revolute": KindBounds(mean=0.0026, case_mean=0.0135, max=0.035, links=0.014),
    "prismatic": KindBounds(mean=0.0002, case_mean=0.0004, max=0.00045, links=0.00045),
}
IMPORTED_BOUNDS = {
    "revolute": KindBounds(mean=0.0035, case_mean=0.007, max=0.022, links=0.0065),
    "prismatic": KindBounds(mean=0.0002, case_mean=0.00025, max=0.0004, links=0.00045, other_joints=0.00035),
}
# Meta-World's faucet knob, a light part turned near its axis: its mean gap
# is 0.0079 rad on an AMD EPYC host without AVX-512 and was under the kind's
# 0.007 on the AVX-512 hosts where the bounds were set, with the same code
# and packages on both (max and link points stay within the kind's bounds).
# A stated bound at about 1.5x the larger gap, as for GAPS.
IMPORTED_CASE_MEANS = {"faucet knob_Joint_1": 0.012}
# Chains and light parts, where PyBullet's 50 sweeps are far from converged
# (golden.known_gaps): stated bounds at about 1.5x today's gap, so that the
# gap cannot grow unseen. Mean, max, other joints, link points.
GAPS = {
    "flap on a door, pulled out": (1.6, 1.6, 0.32, 0.17),
    "flap on an open door, pulled along its tangent": (1.8, 1.8, 0.3, 0.2),
    "tray out of a door, then across": (0.012, 0.027, 0.62, 0.044),
    "50 g switch flicked up and down": (0.6, 0.6, OTHER_JOINTS, 0.025),
}


# A part hinged on a moving part (the TrashCan flap on its lid): the lid is
# in the grasped chain, which umpnet solves alone and PyBullet with the whole
# body, so the lid drifts apart by about 0.001 rad. A stated bound at about
# 2.5x that, as for the families' other bounds.
CHAIN_OTHER_JOINTS = 0.0025


def _within(r, mean, worst, links, others=OTHER_JOINTS):
    """The failures of one result against its bounds, as text."""
    found = {
        "mean": (r.deviation.mean(), mean),
        "max": (r.deviation.max(), worst),
        "link points": (r.link_deviation, links),
        "other joints": (r.other_joint_deviation, others),
    }
    return [f"{r.case.name}: {k} {v:.5f} > {b}" for k, (v, b) in found.items() if v > b]


def _check_kinds(results, bounds, case_means=None):
    """`case_means` replaces the kind's per-case mean bound for the cases it
    names (object and joint, without the folder)."""
    failures = []
    for kind, b in bounds.items():
        of_kind = [r for r in results if r.case.kind == kind]
        assert of_kind, kind
        mean = float(np.concatenate([r.deviation for r in of_kind]).mean())
        if mean > b.mean:
            failures.append(f"{kind}: mean {mean:.5f} over {len(of_kind)} cases > {b.mean}")
        for r in of_kind:
            case_mean = (case_means or {}).get(r.case.name.split("/", 1)[-1], b.case_mean)
            others = CHAIN_OTHER_JOINTS if D.on_a_moving_part(r.case.urdf, r.case.joint) else b.other_joints
            failures += _within(r, case_mean, b.max, b.links, others)
    assert not failures, "\n".join(failures)


def test_cabinet_trajectories_match_pybullet(cabinet):
    _print(cabinet.values())
    assert set(cabinet) == set(CABINET)
    failures = [f for name, r in cabinet.items() for f in _within(r, *CABINET[name])]
    assert not failures, "\n".join(failures)


def test_chains_and_light_parts_stay_within_their_stated_gaps(tmp_path):
    import golden

    with D.StdoutToStderr():
        results = {c.name: D.run_case(c) for c in golden.known_gaps(tmp_path)}
    _print(results.values())
    assert set(results) == set(GAPS)
    failures = [f for name, r in results.items() for f in _within(r, *GAPS[name][:2], GAPS[name][3], GAPS[name][2])]
    assert not failures, "\n".join(failures)
    # The 50 g switch: PyBullet flicks it to a limit, umpnet's solve does not move it.
    switch = results["50 g switch flicked up and down"]
    assert np.abs(switch.umpnet).max() < 0.01 and np.abs(switch.reference).max() > 0.3


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
    _check_kinds(families, FAMILIES)
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
    # Imported objects are tested at the scale their object_meta_info.json gives.
    assert all(r.case.scale != 1.0 for r in imported)
    _check_kinds(imported, IMPORTED_BOUNDS, IMPORTED_CASE_MEANS)
    moved = np.concatenate([np.abs(np.diff(r.reference)) for r in imported])
    assert (moved > 0.05).sum() > 10
