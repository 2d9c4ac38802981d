"""A gymnasium interface to umpnet (optional: needs ``gymnasium``).

The action is two-phase, as in the paper: the first step takes a pixel
(``{"phase": 0, "pixel": [row, col]}``), later steps a direction
(``{"phase": 1, "direction": [x, y, z]}``). The observation holds the
10-channel image, the reference image and the phase.

Rewards and ends follow the paper's protocol (docs/physics-and-protocol.md),
in units of delta (0.15 rad or m):

- ``umpnet/Explore-v0``: the reward is how far a step takes the joint beyond
  the farthest it has been from where it was grasped (new states only); the
  episode ends once the joint is near a limit, having moved.
- ``umpnet/Goal-v0``: the reward is the step's progress toward the goal
  (negative when it moves away); the episode ends in success once the joint
  is within the protocol's threshold of the goal, or crosses it.

A grasp on nothing movable (or, in the goal task, on the wrong part) ends the
episode. The direction budget is the category's (the paper's), unless
``max_steps`` is given. ``info`` carries ``success`` and ``elapsed_steps``.

Observations are fresh arrays, as gymnasium's wrappers (frame stacks,
recorders) expect. ``copy=False`` returns the environment's reused buffers
instead (the zero-copy path of ``umpnet.Env``): faster, but each step
rewrites the previous observation.
"""

from __future__ import annotations

from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ._umpnet import Env, categories

DELTA = 0.15

# The paper's per-category budgets of direction actions (defined once, in Rust).
BUDGETS = {name: budget for name, _, budget in categories()}
MAX_BUDGET = max(BUDGETS.values())


class UmpnetEnv(gym.Env):
    metadata: ClassVar[dict] = {"render_modes": ["rgb_array"]}

    def __init__(self, task="exploration", max_steps=None, resolution=(96, 128), render_mode=None, **env_kwargs):
        self.task, self.max_steps, self.render_mode = task, max_steps, render_mode
        h, w = resolution
        self._seed = env_kwargs.pop("seed", 0)
        env_kwargs.setdefault("copy", True)
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
        self._scene = {}
        self._grasp = {}

    def _observation(self, obs):
        return {"image": obs["image"], "reference": obs["reference"], "phase": self._phase}

    def _budget(self):
        if self.max_steps is not None:
            return int(self.max_steps)
        return BUDGETS.get(self._scene.get("category"), 10)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self._env = Env(seed=int(seed), **self._kwargs)
        scene = (options or {}).get("scene")
        self._obs = self._env.reset(scene)
        self._phase, self._t = 0, 0
        self._scene = self._env.scene
        self._grasp = {}
        return self._observation(self._obs), {"scene": self._scene, "success": False, "elapsed_steps": 0}

    def step(self, action):
        if self._phase == 0:
            row, col = (int(v) for v in action["pixel"])
            self._obs, info = self._env.step_position(row, col)
            self._phase = 1
            terminated = not info["valid"]
            if info["valid"]:
                self._grasp = {
                    "joint": info["joint"],
                    "start": self._env.joint_positions()[info["joint"]],
                    "farthest": 0.0,
                    "limits": info["limits"],
                    "threshold": info["threshold"],
                }
            return self._observation(self._obs), 0.0, terminated, False, {**info, "success": False, "elapsed_steps": 0}
        direction = np.asarray(action["direction"], dtype=np.float32)
        if not np.all(np.isfinite(direction)) or np.linalg.norm(direction) < 1e-6:
            direction = np.array([0.0, 0.0, 1.0], dtype=np.float32)
        self._obs, labels, info = self._env.step_direction(direction.tolist())
        self._t += 1
        reward, success, terminated = self._score(info)
        truncated = not terminated and self._t >= self._budget()
        info = {**info, **labels, "success": success, "elapsed_steps": self._t}
        return self._observation(self._obs), reward, terminated, truncated, info

    def _score(self, info):
        """(reward, success, terminated) of one direction step, per the paper's protocol."""
        g = self._grasp
        before, after = info["joint_before"], info["joint_after"]
        lower, upper = g["limits"]
        thr = g["threshold"]
        if self.task == "exploration":
            distance = abs(after - g["start"])
            reward = max(0.0, distance - g["farthest"]) / DELTA
            g["farthest"] = max(g["farthest"], distance)
            at_limit = distance > thr and (after < lower + thr or after > upper - thr)
            return reward, bool(at_limit), bool(at_limit)
        goal = self._scene["goal"]["joints"][g["joint"]]
        reward = (abs(before - goal) - abs(after - goal)) / DELTA
        reached = (
            abs(after - goal) < thr or (before > goal and after < goal + thr) or (before < goal and after > goal - thr)
        )
        return reward, bool(reached), bool(reached)

    def render(self):
        if self._obs is None:
            return None
        return (np.clip(self._obs["image"][..., 3:6], 0, 1) * 255).astype(np.uint8)


# The position step plus the largest budget: TimeLimit never cuts an episode
# short of its category's budget.
gym.register(
    id="umpnet/Explore-v0",
    entry_point="umpnet.gym:UmpnetEnv",
    kwargs={"task": "exploration"},
    max_episode_steps=MAX_BUDGET + 1,
)
gym.register(
    id="umpnet/Goal-v0", entry_point="umpnet.gym:UmpnetEnv", kwargs={"task": "goal"}, max_episode_steps=MAX_BUDGET + 1
)
