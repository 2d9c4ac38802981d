"""PyBullet's answers to fixed action sequences, stored as test data for the
Rust tests of the `reference` physics (crates/sim/tests/pybullet_golden.rs),
so that `cargo test` (and cargo-mutants) hold the action to the paper's
simulator without Python.

    .venv/bin/python tests/reference/golden.py   # rewrites crates/sim/tests/data/

The cases: the differential suite's cabinet (differential.py) and a hatch
driven to both its limits (neither at 0). Directions are
resolved once here and stored as vectors; the Rust test replays them as
they are. `--gaps` prints the cases where the two part ways (known_gaps).
"""

from __future__ import annotations

import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import pybullet

sys.path.insert(0, str(Path(__file__).resolve().parent))
import differential as D

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "crates" / "sim" / "tests" / "data"

# A door (hinged about -z at its left edge) carrying a flap hinged along its
# lower edge and a tray that slides out of it; on the base, a hatch whose
# limits are both away from 0 and a light switch. Grasping the flap or the tray loads two joints at once: the known
# gaps below.
PARTS_URDF = """<?xml version="1.0"?>
<robot name="parts">
  <link name="base">
    <inertial><origin xyz="0 0 0.5"/><mass value="10"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><origin xyz="0 0 0.5"/><geometry><box size="0.6 0.5 1.0"/></geometry></visual>
  </link>
  <link name="door">
    <inertial><origin xyz="0.3 -0.01 0"/><mass value="1.5"/><inertia ixx="0.05" ixy="0" ixz="0" iyy="0.09" iyz="0" izz="0.045"/></inertial>
    <visual><origin xyz="0.3 -0.01 0"/><geometry><box size="0.6 0.02 0.6"/></geometry></visual>
  </link>
  <joint name="door_hinge" type="revolute">
    <parent link="base"/><child link="door"/>
    <origin xyz="-0.3 -0.25 0.6"/><axis xyz="0 0 -1"/>
    <limit lower="0" upper="1.57" effort="100" velocity="1"/>
  </joint>
  <link name="flap">
    <inertial><origin xyz="0 -0.01 0.1"/><mass value="0.4"/><inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.002"/></inertial>
    <visual><origin xyz="0 -0.01 0.1"/><geometry><box size="0.3 0.02 0.2"/></geometry></visual>
  </link>
  <joint name="flap_hinge" type="revolute">
    <parent link="door"/><child link="flap"/>
    <origin xyz="0.4 -0.02 -0.25"/><axis xyz="-1 0 0"/>
    <limit lower="0" upper="1.4" effort="100" velocity="1"/>
  </joint>
  <link name="tray">
    <inertial><origin xyz="0 0.1 0"/><mass value="0.6"/><inertia ixx="0.003" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.004"/></inertial>
    <visual><origin xyz="0 0.1 0"/><geometry><box size="0.2 0.2 0.04"/></geometry></visual>
  </link>
  <joint name="tray_slide" type="prismatic">
    <parent link="door"/><child link="tray"/>
    <origin xyz="0.3 -0.02 0.15"/><axis xyz="0 -1 0"/>
    <limit lower="0" upper="0.15" effort="100" velocity="1"/>
  </joint>
  <link name="hatch">
    <inertial><origin xyz="0 -0.01 -0.2"/><mass value="2"/><inertia ixx="0.03" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.01"/></inertial>
    <visual><origin xyz="0 -0.01 -0.2"/><geometry><box size="0.2 0.02 0.4"/></geometry></visual>
  </link>
  <joint name="hatch_hinge" type="revolute">
    <parent link="base"/><child link="hatch"/>
    <origin xyz="-0.15 -0.25 0.45"/><axis xyz="1 0 0"/>
    <limit lower="-0.6" upper="0.3" effort="100" velocity="1"/>
  </joint>
  <link name="switch">
    <inertial><origin xyz="0 -0.02 0.02"/><mass value="0.05"/><inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial>
    <visual><origin xyz="0 -0.02 0.02"/><geometry><box size="0.03 0.04 0.06"/></geometry></visual>
  </link>
  <joint name="switch_toggle" type="revolute">
    <parent link="base"/><child link="switch"/>
    <origin xyz="0.2 -0.25 0.15"/><axis xyz="1 0 0"/>
    <limit lower="-0.4" upper="0.4" effort="100" velocity="1"/>
  </joint>
</robot>
"""


def parts_cases(folder: Path) -> list[D.Case]:
    urdf = str(folder / "parts.urdf")
    Path(urdf).write_text(PARTS_URDF)
    # Both limits away from 0: out to -0.6 rad, then in to 0.3 rad.
    hatch = D.Case(
        "hatch along its arc out to its lower limit, then in to its upper",
        urdf=urdf,
        joint="hatch_hinge",
        link="hatch",
        kind="revolute",
        point=[-0.15, -0.27, 0.07],
        directions=["-tangent"] * 5 + ["tangent"] * 6,
    )
    hatch.point = D._world(hatch, hatch.point)
    return [hatch]


def known_gaps(folder: Path) -> list[D.Case]:
    """Cases where umpnet and PyBullet part ways (not stored; `--gaps` prints
    them), all where PyBullet's 50 sweeps are far from converged:
    - parts on a chain of two joints: PyBullet lets a light flap hinged on a
      door pass its lower limit by more than a radian, where umpnet's solve
      holds it; a tray sliding out of a door ends 0.02-0.03 m off;
    - a 50 g switch on this body: PyBullet flicks it to its limits in one
      action, umpnet does not move it. Before the hatch was added to the body,
      PyBullet did not move it either: its result depends on the body's
      other links, which umpnet's chain-only solve leaves out."""
    urdf = str(folder / "parts.urdf")
    Path(urdf).write_text(PARTS_URDF)
    flap = {"urdf": urdf, "joint": "flap_hinge", "link": "flap", "kind": "revolute"}
    up, down = [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]
    cases = [
        D.Case("flap on a door, pulled out", point=[0.1, -0.28, 0.45], directions=[[0.0, -1.0, 0.0]] * 6, **flap),
        D.Case(
            "flap on an open door, pulled along its tangent",
            point=[0.1, -0.28, 0.45],
            directions=["tangent"] * 6,
            start={"door_hinge": 0.5, "flap_hinge": 0.2},
            **flap,
        ),
        D.Case(
            "tray out of a door, then across",
            urdf=urdf,
            joint="tray_slide",
            link="tray",
            kind="prismatic",
            point=[0.0, -0.28, 0.75],
            directions=[[0.0, -1.0, 0.0]] * 3 + [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0]],
        ),
        D.Case(
            "50 g switch flicked up and down",
            urdf=urdf,
            joint="switch_toggle",
            link="switch",
            kind="revolute",
            point=[0.2, -0.29, 0.2],
            directions=[up, up, down, down, down, "tangent", "-tangent", "tangent"],
        ),
    ]
    for c in cases:
        c.point = D._world(c, c.point)
    return cases


def record(result: D.Result) -> dict:
    c = result.case
    return {
        "name": c.name,
        "urdf": Path(c.urdf).name,
        "joint": c.joint,
        "link": c.link,
        "kind": c.kind,
        "position": list(c.position),
        "orientation": list(c.orientation),
        "scale": c.scale,
        "start": c.start,
        "point_in_world": [float(v) for v in c.point],
        # The grasp's approach stops a few millimetres short of the point.
        "gripper_after_grasp": [round(v, 7) for v in result.reference_grasp],
        "actions": [
            {
                "direction": [round(v, 7) for v in d],
                "joint_after": round(float(q), 6),
                "steps": steps,
                "gripper_after": [round(v, 6) for v in mount],
            }
            for d, q, steps, mount in zip(
                result.directions, result.reference, result.reference_steps, result.reference_mount, strict=True
            )
        ],
        # umpnet's answers when the file was written, for the reader; the test
        # compares with PyBullet's.
        "umpnet_joint_after": [round(float(v), 6) for v in result.umpnet],
        "umpnet_steps": result.umpnet_steps,
    }


def main() -> None:
    if "--gaps" in sys.argv:
        with tempfile.TemporaryDirectory() as tmp:
            print(D.table([D.run_case(c) for c in known_gaps(Path(tmp))]))
        return
    OUT.mkdir(parents=True, exist_ok=True)
    cases = D.cabinet_cases(OUT) + parts_cases(OUT)
    results = [D.run_case(c) for c in cases]
    print(D.table(results))
    for r in results:
        ratio = np.array(r.umpnet_steps) / np.maximum(1, np.array(r.reference_steps))
        print(f"{r.case.name}: steps umpnet/pybullet {ratio.min():.2f}-{ratio.max():.2f}")
    data = {
        "about": "PyBullet's answers to fixed actions; written by tests/reference/golden.py",
        "pybullet": pybullet.getAPIVersion(),
        "cases": [record(r) for r in results],
    }
    path = OUT / "pybullet_actions.json"
    path.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {path} ({len(results)} cases, {sum(len(r.reference) for r in results)} actions)")
    assert not math.isnan(sum(sum(r.reference) for r in results))


if __name__ == "__main__":
    main()
