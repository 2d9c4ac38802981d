"""``umpnet.Policy``: the Rust policy runtime, with ``act`` for gymnasium."""

from __future__ import annotations

import numpy as np

from ._umpnet import Policy as _Policy


class Policy(_Policy):
    """The Rust policy runtime on an exported model package
    (``Policy(model_dir, seed=0, threads=1)``).

    ``position`` and ``direction_batch`` are the runtime's two decisions;
    ``act`` takes one observation of ``umpnet.gym``'s environments and returns
    the action they take, so the shipped policy drives them directly::

        policy = umpnet.Policy("models/umpnet-small")
        env = gym.make("umpnet/Goal-v0", resolution=policy.resolution)
        obs, _ = env.reset(seed=0)
        obs, reward, terminated, truncated, info = env.step(policy.act(obs, "goal"))
    """

    def act(self, obs: dict, task: str = "exploration") -> dict:
        """The gym action for ``obs``: the grasp pixel in phase 0, then a
        direction (straight up when the policy stops, which the environment
        takes as a move that ends nothing). ``task`` is ``exploration`` or
        ``goal``; toward a goal, the grasp and every direction read
        ``obs["reference"]`` as the goal observation."""
        if task not in ("exploration", "goal"):
            raise ValueError(f"task {task!r}: expected 'exploration' or 'goal'")
        image = np.asarray(obs["image"], np.float32)
        reference = np.asarray(obs["reference"], np.float32)
        if int(np.asarray(obs["phase"])) == 0:
            row, col = self.position(image, reference if task == "goal" else None)
            return {"phase": 0, "pixel": np.array([row, col], np.int64), "direction": np.zeros(3, np.float32)}
        pixel = np.asarray(obs["gripper_pixel"], np.int64).reshape(1, 2)
        mode = "goal" if task == "goal" else "explore"
        decision = self.direction_batch(image[None], reference[None], pixel, mode)[0]
        direction = decision["direction"] if decision["direction"] is not None else [0.0, 0.0, 1.0]
        return {"phase": 1, "pixel": np.zeros(2, np.int64), "direction": np.asarray(direction, np.float32)}
