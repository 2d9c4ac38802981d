"""What the gym environments observe (``obs_mode=``), in ManiSkill's terms:

- ``image`` (default): the 10-channel observation and its reference, as
  ``umpnet.Policy`` reads them (``Policy.act`` needs this mode).
- ``rgbd``: colour (uint8) and depth (metres, 0 = no return) of the current
  and the reference frame, with the camera's intrinsics and
  ``world_from_camera``.
- ``pointcloud``: one point per pixel in the world frame (xyz, rgb, normal,
  and ``valid`` where the camera saw something), for the current and the
  reference frame.
- ``state``: privileged simulator state, for policies that do not look:
  every joint's value, the reference's (the start when exploring, the goal
  in the goal task), which joints the object has, and the grasped joint.

Every mode also has ``phase`` and ``gripper_pixel``. Shapes are fixed: a
state pads the joints to ``MAX_JOINTS``.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

OBS_MODES = ("image", "rgbd", "pointcloud", "state")
# An object has at most 64 links, so at most 63 joints (the URDF loader's limit).
MAX_JOINTS = 64
# The simulator's extent (m) and a continuous joint's range (rad).
MAX_COORDINATE = 1000.0


def check(mode: str) -> str:
    if mode not in OBS_MODES:
        raise ValueError(f"obs_mode {mode!r}: expected one of {', '.join(OBS_MODES)}")
    return mode


def _box(low, high, shape, dtype):
    return spaces.Box(np.full(shape, low, dtype), np.full(shape, high, dtype), dtype=dtype)


def space(mode: str, h: int, w: int) -> spaces.Dict:
    """The observation space of one environment at h x w."""
    gripper = spaces.Box(np.array([-1, -1]), np.array([h - 1, w - 1]), shape=(2,), dtype=np.int64)
    common = {"phase": spaces.Discrete(2), "gripper_pixel": gripper}
    if mode == "image":
        # Per channel: world x, y, z, colour in [0, 1], unit normal, depth in metres.
        low = np.array([-MAX_COORDINATE] * 3 + [0.0] * 3 + [-1.0] * 3 + [0.0], np.float32)
        high = np.array([MAX_COORDINATE] * 3 + [1.0] * 3 + [1.0] * 3 + [MAX_COORDINATE], np.float32)
        image = spaces.Box(np.broadcast_to(low, (h, w, 10)), np.broadcast_to(high, (h, w, 10)), dtype=np.float32)
        return spaces.Dict({"image": image, "reference": image, **common})
    if mode == "rgbd":
        rgb = _box(0, 255, (h, w, 3), np.uint8)
        depth = _box(0.0, MAX_COORDINATE, (h, w, 1), np.float32)
        return spaces.Dict(
            {
                "rgb": rgb,
                "depth": depth,
                "reference_rgb": rgb,
                "reference_depth": depth,
                "intrinsics": _box(-1e6, 1e6, (3, 3), np.float32),
                "world_from_camera": _box(-MAX_COORDINATE, MAX_COORDINATE, (4, 4), np.float32),
                **common,
            }
        )
    if mode == "pointcloud":
        n = h * w
        xyz = _box(-MAX_COORDINATE, MAX_COORDINATE, (n, 3), np.float32)
        rgb = _box(0, 255, (n, 3), np.uint8)
        normal = _box(-1.0, 1.0, (n, 3), np.float32)
        valid = spaces.MultiBinary(n)
        cloud = {"xyz": xyz, "rgb": rgb, "normal": normal, "valid": valid}
        return spaces.Dict({**cloud, **{f"reference_{k}": v for k, v in cloud.items()}, **common})
    joints = _box(-MAX_COORDINATE, MAX_COORDINATE, (MAX_JOINTS,), np.float32)
    return spaces.Dict(
        {
            "joints": joints,
            "reference_joints": joints,
            "joint_mask": spaces.MultiBinary(MAX_JOINTS),
            "grasped_joint": spaces.Box(-1, MAX_JOINTS - 1, shape=(), dtype=np.int64),
            **common,
        }
    )


def _rgb(image):
    return (np.clip(image[..., 3:6], 0, 1) * 255).astype(np.uint8)


def _cloud(image, prefix=""):
    flat = image.reshape(*image.shape[:-3], -1, 10)
    return {
        f"{prefix}xyz": np.ascontiguousarray(flat[..., 0:3]),
        f"{prefix}rgb": _rgb(flat),
        f"{prefix}normal": np.ascontiguousarray(flat[..., 6:9]),
        f"{prefix}valid": (flat[..., 9] > 0).astype(np.int8),
    }


def _padded(values, batch):
    """Joint values padded to MAX_JOINTS, and the mask of the real ones."""
    rows = list(values) if batch else [values]
    out = np.zeros((len(rows), MAX_JOINTS), np.float32)
    mask = np.zeros((len(rows), MAX_JOINTS), np.int8)
    for i, row in enumerate(rows):
        row = np.asarray(row, np.float32)[:MAX_JOINTS]
        out[i, : len(row)] = row
        mask[i, : len(row)] = 1
    return (out, mask) if batch else (out[0], mask[0])


def convert(mode, obs, phase, gripper_pixel, state=None):
    """One (or a batch of) environment observation(s) in ``mode``. ``obs`` is
    the Rust environment's dict; ``state`` (mode ``state`` only) holds
    ``joints``, ``reference_joints`` (per environment, a list each) and
    ``grasped_joint``."""
    common = {"phase": phase, "gripper_pixel": np.asarray(gripper_pixel, np.int64).copy()}
    image, reference = obs["image"], obs["reference"]
    if mode == "image":
        return {"image": image, "reference": reference, **common}
    if mode == "rgbd":
        return {
            "rgb": _rgb(image),
            "depth": np.ascontiguousarray(image[..., 9:10]),
            "reference_rgb": _rgb(reference),
            "reference_depth": np.ascontiguousarray(reference[..., 9:10]),
            "intrinsics": np.asarray(obs["intrinsics"], np.float32).copy(),
            "world_from_camera": np.asarray(obs["world_from_camera"], np.float32).copy(),
            **common,
        }
    if mode == "pointcloud":
        return {**_cloud(image), **_cloud(reference, "reference_"), **common}
    batch = image.shape[:-3]
    joints, mask = _padded(state["joints"], batch)
    reference_joints, _ = _padded(state["reference_joints"], batch)
    return {
        "joints": joints,
        "reference_joints": reference_joints,
        "joint_mask": mask,
        "grasped_joint": np.asarray(state["grasped_joint"], np.int64),
        **common,
    }


def reference_joints(scene):
    """The joints of the state an episode is judged against: the goal's, or the start's."""
    goal = scene.get("goal")
    return goal["joints"] if goal else scene["joints"]
