"""A gymnasium interface to umpnet (optional: needs ``gymnasium``).

The action is two-phase, as in the paper: the first step takes a pixel
(``{"phase": 0, "pixel": [row, col]}``), later steps a direction
(``{"phase": 1, "direction": [x, y, z]}``). The observation holds the
10-channel image, the reference image and the phase. The reward is the
joint change in units of delta (exploration: forward moves; goal: moves
toward the goal).
"""

from __future__ import annotations

from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ._umpnet import Env

DELTA = 0.15


class UmpnetEnv(gym.Env):
    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"]}

    def __init__(self, task="exploration", max_steps=10, resolution=(96, 128), render_mode=None, **env_kwargs):
        self.task, self.max_steps, self.render_mode = task, max_steps, render_mode
        h, w = resolution
        self._seed = env_kwargs.pop("seed", 0)
        self._kwargs = dict(task=task, resolution=resolution, **env_kwargs)
        self._env = Env(seed=self._seed, **self._kwargs)
        image = spaces.Box(-np.inf, np.inf, shape=(h, w, 10), dtype=np.float32)
        self.observation_space = spaces.Dict({"image": image, "reference": image, "phase": spaces.Discrete(2)})
        self.action_space = spaces.Dict(
            {
                "phase": spaces.Discrete(2),
                "pixel": spaces.MultiDiscrete([h, w]),
                "direction": spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32),
            }
        )
        self._obs = None
        self._phase = 0
        self._t = 0

    def _observation(self, obs):
        return {"image": obs["image"], "reference": obs["reference"], "phase": self._phase}

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self._env = Env(seed=int(seed), **self._kwargs)
        scene = (options or {}).get("scene")
        self._obs = self._env.reset(scene)
        self._phase, self._t = 0, 0
        return self._observation(self._obs), {"scene": self._env.scene}

    def step(self, action):
        if self._phase == 0:
            row, col = (int(v) for v in action["pixel"])
            self._obs, info = self._env.step_position(row, col)
            self._phase = 1
            terminated = not info["valid"]
            return self._observation(self._obs), 0.0, terminated, False, info
        direction = np.asarray(action["direction"], dtype=np.float32)
        if not np.all(np.isfinite(direction)) or np.linalg.norm(direction) < 1e-6:
            direction = np.array([0.0, 0.0, 1.0], dtype=np.float32)
        self._obs, labels, info = self._env.step_direction(direction.tolist())
        self._t += 1
        wanted = 1 if self.task == "exploration" else -1
        reward = float(labels["r_dist"] / DELTA) if labels["aot"] == wanted else 0.0
        truncated = self._t >= self.max_steps
        return self._observation(self._obs), reward, False, truncated, {**info, **labels}

    def render(self):
        if self._obs is None:
            return None
        return (np.clip(self._obs["image"][..., 3:6], 0, 1) * 255).astype(np.uint8)


gym.register(id="umpnet/Explore-v0", entry_point="umpnet.gym:UmpnetEnv", kwargs={"task": "exploration"})
gym.register(id="umpnet/Goal-v0", entry_point="umpnet.gym:UmpnetEnv", kwargs={"task": "goal", "max_steps": 15})
