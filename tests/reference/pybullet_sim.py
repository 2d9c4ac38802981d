"""The paper's simulator, re-implemented in PyBullet after the released code
(`sim.py` of real-stanford/umpnet: a force-limited 3-axis mount, a
point-to-point suction constraint, 240 Hz), as the reference of the
differential suite. It models only what the action primitive needs: the
object, the force-limited 3-axis mount, the point-to-point suction and the
0.18 m move with its stopping rule. No rendering.

Written for umpnet's tests; it shares no code with the paper's repository.
"""

from __future__ import annotations

import os
import sys
import tempfile
from dataclasses import dataclass

import numpy as np
import pybullet
from pybullet_utils import bullet_client

MOUNT_HOME = np.array([0.0, -2.0, 2.0])
MOUNT_FORCE = 1500.0
SUCTION_FORCE = 2000.0
ACTION_GAIN = 0.002
REALIGN_GAIN = 0.02
MAX_STEPS = 240 * 8
STILL_DISPLACEMENT = 1e-4
STILL_STEPS = 3

# x, y, z prismatic axes in world, the carriage (100 kg) last; the tip parts of
# the reference (0.5 kg) ride on it. No collision shapes anywhere.
_MOUNT_URDF = """<?xml version="1.0"?>
<robot name="mount">
  <link name="base"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="x" type="prismatic"><parent link="base"/><child link="lx"/><axis xyz="1 0 0"/>
    <limit effort="1000" lower="-1000" upper="1000" velocity="5"/></joint>
  <link name="lx"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="y" type="prismatic"><parent link="lx"/><child link="ly"/><axis xyz="0 1 0"/>
    <limit effort="1000" lower="-1000" upper="1000" velocity="5"/></joint>
  <link name="ly"><inertial><mass value="0"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="z" type="prismatic"><parent link="ly"/><child link="lz"/><axis xyz="0 0 1"/>
    <limit effort="1000" lower="-1000" upper="1000" velocity="5"/></joint>
  <link name="lz"><inertial><mass value="100.5"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
</robot>
"""
_CARRIAGE = 2  # link index of "lz": the suction attaches at its origin


class StdoutToStderr:
    """PyBullet's C code prints to file descriptor 1; keep it off a report (and its JSON)."""

    def __enter__(self):
        sys.stdout.flush()
        self.saved = os.dup(1)
        os.dup2(2, 1)

    def __exit__(self, *_):
        sys.stdout.flush()
        os.dup2(self.saved, 1)
        os.close(self.saved)


# One mount file per process, in a folder removed when the process exits (a
# folder per simulator left dozens behind in /tmp after each test run).
_MOUNT_DIR: tempfile.TemporaryDirectory | None = None


def _mount_file() -> str:
    global _MOUNT_DIR
    if _MOUNT_DIR is None:
        _MOUNT_DIR = tempfile.TemporaryDirectory(prefix="umpnet-ref-")
        with open(os.path.join(_MOUNT_DIR.name, "mount.urdf"), "w") as f:
            f.write(_MOUNT_URDF)
    return os.path.join(_MOUNT_DIR.name, "mount.urdf")


@dataclass
class Outcome:
    joint_before: float
    joint_after: float
    steps: int


class ReferenceSim:
    """One object (fixed base) in a zero-gravity PyBullet world at 240 Hz."""

    def __init__(
        self,
        urdf: str,
        position=(0.0, -0.5, 0.0),
        orientation=(0.0, 0.0, 0.0, 1.0),
        scale: float = 1.0,
    ):
        self.bc = bullet_client.BulletClient(connection_mode=pybullet.DIRECT)
        self.bc.setGravity(0, 0, 0)
        self.body = self.bc.loadURDF(
            urdf,
            basePosition=list(position),
            baseOrientation=list(orientation),
            globalScaling=scale,
            useFixedBase=True,
            flags=self.bc.URDF_USE_MATERIAL_COLORS_FROM_MTL,
        )
        # PyBullet joint i moves link i.
        self.joint_index = {}
        self.link_index = {-1: -1}
        for i in range(self.bc.getNumJoints(self.body)):
            info = self.bc.getJointInfo(self.body, i)
            self.joint_index[info[1].decode()] = i
            self.link_index[info[12].decode()] = i
        self.mount = None
        self._point_in_link = None
        self._link = None
        self._mount_file = _mount_file()

    def close(self):
        self.bc.disconnect()

    def set_joint(self, name: str, value: float):
        self.bc.resetJointState(self.body, self.joint_index[name], value)

    def joint(self, name: str) -> float:
        return self.bc.getJointState(self.body, self.joint_index[name])[0]

    def _link_frame(self, link: int):
        # Position and orientation of the link's inertial frame: the frame in
        # which PyBullet's constraints (and the reference's suction point) live.
        s = self.bc.getLinkState(self.body, link, computeForwardKinematics=True)
        return s[0], s[1]

    def link_world_frame(self, link: int):
        """The link's URDF frame in world (position, xyzw quaternion)."""
        s = self.bc.getLinkState(self.body, link, computeForwardKinematics=True)
        return s[4], s[5]

    def mount_position(self) -> np.ndarray:
        q = [self.bc.getJointState(self.mount, i)[0] for i in range(3)]
        return np.array(q) + MOUNT_HOME

    def _move_to(self, target, gain: float) -> int:
        self.bc.setJointMotorControlArray(
            self.mount,
            [0, 1, 2],
            self.bc.POSITION_CONTROL,
            targetPositions=list(np.asarray(target) - MOUNT_HOME),
            forces=[MOUNT_FORCE] * 3,
            positionGains=[gain] * 3,
        )
        last = np.array([-10.0, -10.0, -10.0])
        still = 0
        for step in range(MAX_STEPS):
            self.bc.stepSimulation()
            now = self.mount_position()
            still += int(np.linalg.norm(now - last) < STILL_DISPLACEMENT)
            last = now
            if still >= STILL_STEPS:
                return step + 1
        return MAX_STEPS

    def suction_point(self) -> np.ndarray:
        pos, orn = self._link_frame(self._link)
        return np.array(self.bc.multiplyTransforms(pos, orn, self._point_in_link, [0, 0, 0, 1])[0])

    def grasp(self, point_in_world, link_name: str):
        """The position action at a world point on a link."""
        self._link = self.link_index[link_name]
        self.mount = self.bc.loadURDF(self._mount_file, basePosition=list(MOUNT_HOME), useFixedBase=True)
        pos, orn = self._link_frame(self._link)
        inv_pos, inv_orn = self.bc.invertTransform(pos, orn)
        self._point_in_link = self.bc.multiplyTransforms(inv_pos, inv_orn, list(point_in_world), [0, 0, 0, 1])[0]
        self._move_to(MOUNT_HOME, REALIGN_GAIN)
        self._move_to(point_in_world, REALIGN_GAIN)
        c = self.bc.createConstraint(
            parentBodyUniqueId=self.body,
            parentLinkIndex=self._link,
            childBodyUniqueId=self.mount,
            childLinkIndex=_CARRIAGE,
            jointType=self.bc.JOINT_POINT2POINT,
            jointAxis=[0, 0, 0],
            parentFramePosition=self._point_in_link,
            childFramePosition=[0, 0, 0],
        )
        self.bc.changeConstraint(c, maxForce=SUCTION_FORCE)

    def move(self, direction, joint_name: str, length: float = 0.18) -> Outcome:
        """One direction action; reports the named joint before and after."""
        before = self.joint(joint_name)
        start = self.suction_point()
        steps = self._move_to(start + np.asarray(direction, float) * length, ACTION_GAIN)
        steps += self._move_to(self.suction_point(), REALIGN_GAIN)
        return Outcome(before, self.joint(joint_name), steps)
