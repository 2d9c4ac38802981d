"""Differential suite: the same URDF, grasp points and scripted directions in
PyBullet (the paper's simulator, `pybullet_sim.py`) and in umpnet's
`reference` physics; trajectories side by side and their deviations.

Run it by hand for the side-by-side table:

    .venv/bin/python tests/reference/differential.py [--physics ideal] [--umpnet target/release/umpnet]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import umpnet
from pybullet_sim import ReferenceSim, StdoutToStderr

ROOT = Path(__file__).resolve().parents[2]

KINDS = ("revolute", "prismatic")  # the joint kinds compared (test_differential.py holds the bounds)

# A cabinet: a door hinged on the left of the front face (0.8 m wide, opens
# toward the camera for positive values), a drawer below it, and a lid on top
# hinged at its back edge. All links carry inertials but the lid, which takes
# the defaults (mass 1, centre of mass at the link origin).
CABINET_URDF = """<?xml version="1.0"?>
<robot name="cabinet">
  <link name="base">
    <inertial><origin xyz="0 0 0.5"/><mass value="10"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><origin xyz="0 0 0.5"/><geometry><box size="0.8 0.5 1.0"/></geometry></visual>
  </link>
  <link name="door">
    <inertial><origin xyz="0.4 -0.01 0"/><mass value="2"/><inertia ixx="0.14" ixy="0" ixz="0" iyy="0.24" iyz="0" izz="0.11"/></inertial>
    <visual><origin xyz="0.4 -0.01 0"/><geometry><box size="0.8 0.02 0.45"/></geometry></visual>
    <collision><origin xyz="0.4 -0.01 0"/><geometry><box size="0.8 0.02 0.45"/></geometry></collision>
  </link>
  <joint name="door_hinge" type="revolute">
    <parent link="base"/><child link="door"/>
    <origin xyz="-0.4 -0.25 0.75"/><axis xyz="0 0 -1"/>
    <limit lower="0" upper="1.57" effort="100" velocity="1"/>
  </joint>
  <link name="drawer">
    <inertial><origin xyz="0 0.2 0"/><mass value="3"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><origin xyz="0 0.2 0"/><geometry><box size="0.7 0.4 0.3"/></geometry></visual>
    <collision><origin xyz="0 0.2 0"/><geometry><box size="0.7 0.4 0.3"/></geometry></collision>
  </link>
  <joint name="drawer_slide" type="prismatic">
    <parent link="base"/><child link="drawer"/>
    <origin xyz="0 -0.25 0.25"/><axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.4" effort="100" velocity="1"/>
  </joint>
  <link name="lid">
    <visual><origin xyz="0 -0.25 0.01"/><geometry><box size="0.8 0.5 0.02"/></geometry></visual>
    <collision><origin xyz="0 -0.25 0.01"/><geometry><box size="0.8 0.5 0.02"/></geometry></collision>
  </link>
  <joint name="lid_hinge" type="revolute">
    <parent link="base"/><child link="lid"/>
    <origin xyz="0 0.25 1.0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1.8" effort="100" velocity="1"/>
  </joint>
</robot>
"""


@dataclass
class Case:
    """One grasp and a list of directions (fixed vectors, or 'tangent'/'-tangent'
    for the current opening direction at the grasp point)."""

    name: str
    urdf: str
    joint: str
    link: str
    point: list
    directions: list
    kind: str
    start: dict = field(default_factory=dict)
    position: tuple = (0.0, -0.5, 0.0)
    orientation: tuple = (0.0, 0.0, 0.0, 1.0)
    scale: float = 1.0


@dataclass
class Result:
    case: Case
    reference: list
    umpnet: list
    ms_reference: float
    ms_umpnet: float
    # Per action: the commanded unit vector, and PyBullet's step count and
    # mount position after it (the golden data of crates/sim/tests, golden.py).
    directions: list = field(default_factory=list)
    reference_steps: list = field(default_factory=list)
    reference_mount: list = field(default_factory=list)
    umpnet_steps: list = field(default_factory=list)
    reference_grasp: list = field(default_factory=list)  # the mount after the grasp
    # Per action: the largest |difference| over the joints not grasped (rad or
    # m; 0 when the object has one joint), and the largest distance (m) between
    # where the two simulators put the same points of each moving link.
    other_joints: list = field(default_factory=list)
    link_points: list = field(default_factory=list)

    @property
    def deviation(self) -> np.ndarray:
        return np.abs(np.array(self.reference) - np.array(self.umpnet))

    @property
    def other_joint_deviation(self) -> float:
        return float(max(self.other_joints, default=0.0))

    @property
    def link_deviation(self) -> float:
        return float(max(self.link_points, default=0.0))


class LinkPoints:
    """Two points fixed on each non-base link (its vertex centroid and the
    vertex farthest from it), found on umpnet's start state and carried into
    PyBullet's link frames, so both simulators' link poses can be compared
    point for point at every step."""

    def __init__(self, art, ref):
        self.links = []
        for link in art.link_names():
            index = ref.link_index.get(link, -1)
            verts = np.array(art.link_vertices(link))
            if index < 0 or len(verts) == 0:
                continue
            centre = verts.mean(axis=0)
            far = int(np.argmax(np.linalg.norm(verts - centre, axis=1)))
            pos, orn = ref.link_world_frame(index)
            inv_pos, inv_orn = ref.bc.invertTransform(pos, orn)
            in_link = [
                ref.bc.multiplyTransforms(inv_pos, inv_orn, list(p), [0, 0, 0, 1])[0] for p in (centre, verts[far])
            ]
            self.links.append((link, index, far, in_link))

    def deviation(self, art, ref) -> float:
        worst = 0.0
        for link, index, far, in_link in self.links:
            verts = np.array(art.link_vertices(link))
            ours = (verts.mean(axis=0), verts[far])
            pos, orn = ref.link_world_frame(index)
            for p_ours, p_link in zip(ours, in_link, strict=True):
                theirs = np.array(ref.bc.multiplyTransforms(pos, orn, p_link, [0, 0, 0, 1])[0])
                worst = max(worst, float(np.linalg.norm(p_ours - theirs)))
        return worst


def _yaw(deg: float) -> tuple:
    h = math.radians(deg) / 2
    return (0.0, 0.0, math.sin(h), math.cos(h))


def _tangent(art, joint: str, sign: float) -> list:
    """The direction a grasp point moves when the joint value grows."""
    _, axis, origin = art.joint_axis(joint)
    axis, origin = np.array(axis), np.array(origin)
    p = np.array(art.gripper_position())
    kind = "prismatic" if np.allclose(np.cross(axis, p - origin), 0) else None
    v = axis if kind else np.cross(axis, p - origin)
    n = np.linalg.norm(v)
    return list(sign * v / n) if n > 1e-9 else [0.0, -1.0, 0.0]


def cabinet_cases(folder: Path) -> list[Case]:
    urdf = str(folder / "cabinet.urdf")
    Path(urdf).write_text(CABINET_URDF)
    door = {"urdf": urdf, "joint": "door_hinge", "link": "door", "kind": "revolute"}
    door_edge = [0.35, -0.27, 0.75]  # 0.75 m from the hinge, on the front face
    drawer = {"urdf": urdf, "joint": "drawer_slide", "link": "drawer", "kind": "prismatic"}
    minus_y, plus_y = [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]
    cases = [
        Case("door, pull along -y", point=door_edge, directions=[minus_y] * 10, **door),
        Case("door, pull along its tangent", point=door_edge, directions=["tangent"] * 10, **door),
        Case(
            "drawer, 5 pulls then 5 pushes",
            point=[0.0, -0.26, 0.25],
            directions=[minus_y] * 5 + [plus_y] * 5,
            **drawer,
        ),
        Case(
            "door, grasp 5 cm from the hinge",
            point=[-0.35, -0.27, 0.75],
            directions=["tangent"] * 4 + [minus_y] * 2,
            **door,
        ),
        Case(
            "lid lifted (no <inertial>)",
            urdf=urdf,
            joint="lid_hinge",
            link="lid",
            kind="revolute",
            point=[0.0, -0.2, 1.02],
            directions=[[0.0, 0.0, 1.0]] * 4 + ["tangent"] * 4 + ["-tangent"] * 2,
        ),
        Case(
            "door, yawed 30 deg and scaled 0.55, along its tangent",
            point=door_edge,
            directions=["tangent"] * 8,
            orientation=_yaw(30),
            scale=0.55,
            **door,
        ),
    ]
    for c in cases:
        c.point = _world(c, c.point)
    return cases


def generated_cases(umpnet_bin: str, folder: Path, per_category: int = 2, actions: int = 6, seed: int = 0):
    """Every generated family, `per_category` instances, every movable joint
    grasped near its part's far edge, under seeded random directions mixed with
    pulls along the opening direction."""
    subprocess.run(
        [umpnet_bin, "--json", "objects", "generate", "--out", str(folder), "--per-category", str(per_category)],
        check=True,
        capture_output=True,
    )
    return folder_cases(sorted(folder.glob("*/*/mobility.urdf")), actions=actions, seed=seed, scaled=False)


def folder_cases(urdfs: list[Path], actions: int = 6, seed: int = 0, scaled: bool = True) -> list[Case]:
    """Every movable joint of each URDF, grasped near its part's far edge, under
    seeded random directions mixed with pulls along the opening direction. With
    `scaled`, each object is placed at the scale of its object_meta_info.json
    (an imported object at its scene size)."""
    rng = np.random.default_rng(seed)
    cases = []
    for urdf in urdfs:
        scale = 1.0
        meta = urdf.with_name("object_meta_info.json")
        if scaled and meta.is_file():
            scale = float(json.loads(meta.read_text())["scale"])
        art = umpnet.Articulation(str(urdf), scale=scale)
        for joint in art.joint_names():
            link, axis, origin = art.joint_axis(joint)
            verts = np.array(art.link_vertices(link))
            kind = _kind(str(urdf), joint)
            if kind is None or len(verts) == 0:
                continue
            axis, origin = np.array(axis), np.array(origin)
            centre = verts.mean(axis=0)
            if kind == "prismatic":
                point = centre
            else:
                radial = (verts - origin) - np.outer((verts - origin) @ axis, axis)
                far = verts[np.argmax(np.linalg.norm(radial, axis=1))]
                point = far + 0.15 * (centre - far)
            dirs = []
            for k in range(actions):
                if k % 2 == 0:
                    d = rng.normal(size=3)
                    dirs.append(list(d / np.linalg.norm(d)))
                else:
                    dirs.append("tangent" if rng.random() < 0.7 else "-tangent")
            u = float(rng.uniform(0.0, 0.4))
            if scaled:
                # Within the joint's range: an imported range need not start at 0.
                lo, hi = _limits(str(urdf), joint)
                factor = scale if kind == "prismatic" else 1.0
                u = factor * (lo + u * (hi - lo))
            cases.append(
                Case(
                    f"{urdf.parent.parent.name}/{urdf.parent.name} {joint}",
                    str(urdf),
                    joint,
                    link,
                    list(point),
                    dirs,
                    kind,
                    start={joint: u},
                    scale=scale,
                )
            )
    return cases


def _kind(urdf: str, joint: str):
    import xml.etree.ElementTree as ET

    for j in ET.parse(urdf).getroot().iter("joint"):
        if j.get("name") == joint:
            t = j.get("type")
            return {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}.get(t)
    return None


def on_a_moving_part(urdf: str, joint: str) -> bool:
    """Whether `joint`'s parent link is itself moved by a joint (a chain)."""
    import xml.etree.ElementTree as ET

    joints = list(ET.parse(urdf).getroot().iter("joint"))
    movable = {j.find("child").get("link") for j in joints if j.get("type") != "fixed" and j.find("child") is not None}
    parent = next((j.find("parent").get("link") for j in joints if j.get("name") == joint), None)
    return parent in movable


def _limits(urdf: str, joint: str) -> tuple[float, float]:
    import xml.etree.ElementTree as ET

    for j in ET.parse(urdf).getroot().iter("joint"):
        if j.get("name") == joint and j.find("limit") is not None:
            lim = j.find("limit")
            return float(lim.get("lower", 0)), float(lim.get("upper", 0))
    return (0.0, 1.0)


def _world(case: Case, point_in_base) -> list:
    """A point given in the unscaled object frame, placed as the case places the object."""
    x, y, z, w = case.orientation
    q = np.array([x, y, z])
    p = case.scale * np.asarray(point_in_base, float)
    rotated = p + 2.0 * np.cross(q, np.cross(q, p) + w * p)
    return list(np.asarray(case.position) + rotated)


def _carried(point, before: np.ndarray, after: np.ndarray) -> list:
    """`point` moved by the rigid motion that takes a link's vertices from
    `before` to `after` (Kabsch: the rotation from the SVD of their covariance)."""
    a, b = before.mean(axis=0), after.mean(axis=0)
    u, _, vt = np.linalg.svd((before - a).T @ (after - b))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return list(rotation @ (np.asarray(point, float) - a) + b)


def run_case(case: Case, physics: str = "reference") -> Result:
    place = {"position": case.position, "orientation": case.orientation, "scale": case.scale}
    art = umpnet.Articulation(case.urdf, physics=physics, **place)
    ref = ReferenceSim(case.urdf, **place)
    try:
        point = case.point
        if case.start:
            # Cases name their grasp point with the object closed: it rides
            # with its link into the start state, so suction still lands on
            # the part (umpnet refuses a grasp away from its link's surface).
            before = np.array(art.link_vertices(case.link))
            art.set_joints(case.start)
            for name in case.start:
                ref.set_joint(name, art.joint(name))
            point = _carried(point, before, np.array(art.link_vertices(case.link)))
        points = LinkPoints(art, ref)
        movable = [j for j in art.joint_names() if _kind(case.urdf, j) is not None and j != case.joint]
        art.grasp(point, case.link)
        ref.grasp(point, case.link)
        trajectory = {"reference": [], "umpnet": []}
        seconds = {"reference": 0.0, "umpnet": 0.0}
        record = {"directions": [], "reference_steps": [], "reference_mount": [], "umpnet_steps": []}
        record.update(other_joints=[], link_points=[])
        record["reference_grasp"] = [float(v) for v in ref.mount_position()]
        for d in case.directions:
            # One commanded vector for both: the opening direction is taken on umpnet's state.
            if isinstance(d, str):
                d = _tangent(art, case.joint, -1.0 if d.startswith("-") else 1.0)
            d = [float(v) for v in d]
            t = time.perf_counter()
            ours = art.move_gripper(d, case.joint)
            seconds["umpnet"] += time.perf_counter() - t
            t = time.perf_counter()
            theirs = ref.move(d, case.joint)
            seconds["reference"] += time.perf_counter() - t
            trajectory["umpnet"].append(ours["joint_after"])
            trajectory["reference"].append(theirs.joint_after)
            record["directions"].append(d)
            record["umpnet_steps"].append(int(ours["steps"]))
            record["reference_steps"].append(theirs.steps)
            record["reference_mount"].append([float(v) for v in ref.mount_position()])
            others = [abs(art.joint(j) - ref.joint(j)) for j in movable]
            record["other_joints"].append(float(max(others, default=0.0)))
            record["link_points"].append(points.deviation(art, ref))
        n = max(1, len(case.directions))
        return Result(
            case,
            trajectory["reference"],
            trajectory["umpnet"],
            1e3 * seconds["reference"] / n,
            1e3 * seconds["umpnet"] / n,
            **record,
        )
    finally:
        ref.close()


def summarize(results: list[Result]) -> dict:
    out = {}
    for kind in KINDS:
        devs = np.concatenate([r.deviation for r in results if r.case.kind == kind] or [np.zeros(0)])
        if len(devs):
            out[kind] = {"steps": len(devs), "mean": float(devs.mean()), "max": float(devs.max())}
    ref_ms = np.median([r.ms_reference for r in results])
    ump_ms = np.median([r.ms_umpnet for r in results])
    out["ms_per_action"] = {"pybullet": float(ref_ms), "umpnet": float(ump_ms), "ratio": float(ref_ms / ump_ms)}
    return out


def table(results: list[Result]) -> str:
    lines = []
    for r in results:
        lines.append(
            f"{r.case.name} ({r.case.kind}; grasped joint mean |d| {r.deviation.mean():.4f} max {r.deviation.max():.4f}, "
            f"other joints max {r.other_joint_deviation:.4f}, link points max {r.link_deviation:.4f} m)"
        )
        lines.append("  pybullet " + " ".join(f"{v:6.3f}" for v in r.reference))
        lines.append("  umpnet   " + " ".join(f"{v:6.3f}" for v in r.umpnet))
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--physics", default="reference", choices=["reference", "ideal"])
    ap.add_argument("--umpnet", default=os.environ.get("UMPNET_BIN", str(ROOT / "target/release/umpnet")))
    ap.add_argument("--per-category", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cases = cabinet_cases(tmp) + generated_cases(a.umpnet, tmp / "objects", a.per_category)
        with StdoutToStderr():
            results = [run_case(c, a.physics) for c in cases]
    summary = summarize(results)
    if a.json:
        print(json.dumps(summary, indent=2))
    else:
        print(table(results))
        print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
