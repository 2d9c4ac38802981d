"""A gymnasium interface to umpnet (optional: needs ``gymnasium``).

The action is two-phase, as in the paper: the first step takes a pixel
(``{"phase": 0, "pixel": [row, col]}``), later steps a direction
(``{"phase": 1, "direction": [x, y, z]}``). The observation holds the
10-channel image, the reference image, the phase and ``gripper_pixel``
(where the gripper holds the object, (-1, -1) before the grasp): what
``umpnet.Policy`` needs, so a learned policy is driven from the observation
alone (``Policy.position(obs["image"], obs["reference"])``, then
``Policy.direction_batch`` with ``obs["gripper_pixel"]``).

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

``render()`` draws the scene again at ``render_size=(height, width)``
(480x640 by default, gripper included), whatever the observation's
resolution, for videos people watch; ``render_size=None`` returns the
observation's own colour instead. ``render_mode="human"`` shows each frame as
it comes, in a window when one can open, else in a PNG file it names once
(``umpnet.viewer``; ``human_frame_path=`` picks the file).

``obs_mode`` chooses what the agent observes: ``image`` (the default, what
``umpnet.Policy`` reads), ``rgbd``, ``pointcloud`` or ``state``
(``umpnet.obs_modes`` describes each).

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
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import obs_modes
from ._umpnet import Env, VecEnv, categories, score_step
from .record import RecordEpisode
from .viewer import Viewer, tile

__all__ = ["RecordEpisode", "UmpnetEnv", "UmpnetVectorEnv", "score"]

# The paper's per-category budgets of direction actions (defined once, in Rust).
BUDGETS = {name: budget for name, _, budget in categories()}
MAX_BUDGET = max(BUDGETS.values())


def score(task, before, after, start, farthest, lower, upper, threshold, goal):
    """Reward and success of direction steps per the paper's protocol, for
    scalars or arrays alike: (reward in units of delta, success, the new
    farthest distance from the start). Success ends the episode. The rule is
    Rust's (``umpnet_eval::rewards``), the one ``umpnet eval`` counts by."""
    arrays = np.broadcast_arrays(
        *(np.asarray(v, np.float64) for v in (before, after, start, farthest, lower, upper, threshold, goal))
    )
    out = [score_step(task, *(float(a[i]) for a in arrays)) for i in np.ndindex(arrays[0].shape)]
    shape = arrays[0].shape
    reward = np.array([o[0] for o in out], np.float64).reshape(shape)
    success = np.array([o[1] for o in out], bool).reshape(shape)
    farther = np.array([o[2] for o in out], np.float64).reshape(shape)
    if not shape:
        return reward[()], success[()], farther[()]
    return reward, success, farther


# One frame per action: a recording plays an episode at a readable pace.
RENDER_FPS = 4
# What render() draws unless told: a size people watch (HEIGHT, WIDTH).
RENDER_SIZE = (480, 640)
RENDER_MODES = ["human", "rgb_array"]


def check_render(render_mode, render_size):
    """The validated render size, (h, w) or None; a bad mode or size is a ValueError."""
    if render_mode not in (None, *RENDER_MODES):
        raise ValueError(f"render_mode {render_mode!r}: expected None, 'human' or 'rgb_array'")
    if render_size is None:
        return None
    return int(render_size[0]), int(render_size[1])


def rgb(image) -> np.ndarray:
    """The colour channels of observations (..., H, W, 10) as uint8 RGB."""
    return (np.clip(np.asarray(image)[..., 3:6], 0, 1) * 255).astype(np.uint8)


class UmpnetEnv(gym.Env):
    metadata: ClassVar[dict] = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS}

    def __init__(
        self, task="exploration", max_steps=None, resolution=(96, 128), render_mode=None, obs_mode="image",
        render_size=RENDER_SIZE, human_frame_path=None, **env_kwargs,
    ):  # fmt: skip
        self.task, self.max_steps, self.render_mode = task, max_steps, render_mode
        self.obs_mode = obs_modes.check(obs_mode)
        # render() at (height, width), drawn again at that size; None: the observation's colour.
        self.render_size = check_render(render_mode, render_size)
        title = f"umpnet {task}"
        self._viewer = Viewer(title, RENDER_FPS, human_frame_path) if render_mode == "human" else None
        h, w = resolution
        self._seed = env_kwargs.pop("seed", 0)
        env_kwargs.setdefault("copy", True)
        self._kwargs = dict(task=task, resolution=resolution, **env_kwargs)
        self._env = Env(seed=self._seed, **self._kwargs)
        self.observation_space, self.action_space = self.spaces(h, w, obs_mode)
        self._obs = None
        self._phase = 0
        self._t = 0
        self._scene = {}
        self._grasp = {}

    @staticmethod
    def spaces(h, w, obs_mode="image"):
        """(observation space, action space) of one environment at h x w."""
        observation = obs_modes.space(obs_modes.check(obs_mode), h, w)
        action = spaces.Dict(
            {
                "phase": spaces.Discrete(2),
                "pixel": spaces.MultiDiscrete([h, w]),
                "direction": spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32),
            }
        )
        return observation, action

    def _observation(self, obs):
        state = None
        if self.obs_mode == "state":
            state = {
                "joints": self._env.joint_positions(),
                "reference_joints": obs_modes.reference_joints(self._env.scene),
                "grasped_joint": self._grasp.get("joint", -1),
            }
        return obs_modes.convert(self.obs_mode, obs, self._phase, obs["gripper_pixel"], state)

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
        self._show()
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
            self._show()
            return self._observation(self._obs), 0.0, terminated, False, {**info, "success": False, "elapsed_steps": 0}
        direction = np.asarray(action["direction"], dtype=np.float32)
        if not np.all(np.isfinite(direction)) or np.linalg.norm(direction) < 1e-6:
            direction = np.array([0.0, 0.0, 1.0], dtype=np.float32)
        self._obs, labels, info = self._env.step_direction(direction.tolist())
        self._t += 1
        reward, success, terminated = self._score(info)
        truncated = not terminated and self._t >= self._budget()
        info = {**info, **labels, "success": success, "elapsed_steps": self._t}
        self._show()
        return self._observation(self._obs), reward, terminated, truncated, info

    def _score(self, info):
        """(reward, success, terminated) of one direction step, per the paper's protocol."""
        g = self._grasp
        # The scene's goal is an f32 written as shortest decimal text: read back
        # as f32, it is the value the simulator holds.
        goal = np.float32(self._scene["goal"]["joints"][g["joint"]]) if self.task == "goal" else np.nan
        reward, success, farthest = score(
            self.task,
            np.float64(info["joint_before"]),
            np.float64(info["joint_after"]),
            np.float64(g["start"]),
            np.float64(g["farthest"]),
            np.float64(g["limits"][0]),
            np.float64(g["limits"][1]),
            np.float64(g["threshold"]),
            np.float64(goal),
        )
        g["farthest"] = float(farthest)
        return float(reward), bool(success), bool(success)

    def _frame(self):
        if self.render_size is not None:
            return self._env.render_rgb(*self.render_size)
        return rgb(self._obs["image"])

    def _show(self):
        """In human mode, every reset and step shows its frame (gymnasium's rule)."""
        if self._viewer is not None:
            self._viewer.show(self._frame())

    def render(self):
        if self._obs is None:
            return None
        if self._viewer is not None:
            self._show()
            return None
        return self._frame()

    def close(self):
        if self._viewer is not None:
            self._viewer.close()
        super().close()


class UmpnetVectorEnv(VectorEnv):
    """``num_envs`` umpnet environments stepped together in Rust threads
    (``umpnet.VecEnv``), as a ``gymnasium.vector.VectorEnv``.

    Spaces, rewards, ends and ``info["success"]``/``info["elapsed_steps"]`` are
    those of ``UmpnetEnv``, batched. Environments reset on the step after they
    end (gymnasium's next-step autoreset): that step's action is ignored, its
    reward is 0 and ``info["reset"]`` is True. Made by
    ``gym.make_vec("umpnet/Explore-v0", num_envs=n)``.

    Environment i draws its scenes from seed ``seed + i``. Observations are
    fresh arrays unless ``copy=False`` (then the VecEnv's reused buffers).
    """

    metadata: ClassVar[dict] = {
        "render_modes": RENDER_MODES,
        "render_fps": RENDER_FPS,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs=1,
        task="exploration",
        max_steps=None,
        max_episode_steps=None,
        resolution=(96, 128),
        render_mode=None,
        obs_mode="image",
        render_size=RENDER_SIZE,
        human_frame_path=None,
        **env_kwargs,
    ):
        self.obs_mode = obs_modes.check(obs_mode)
        self.render_size = check_render(render_mode, render_size)
        self.render_mode = render_mode
        title = f"umpnet {task}, {num_envs} environments"
        self._viewer = Viewer(title, RENDER_FPS, human_frame_path) if render_mode == "human" else None
        self._last = None
        if task not in ("exploration", "goal"):
            raise ValueError(f"task {task!r}: expected 'exploration' or 'goal'")
        self.num_envs, self.task, self.max_steps = int(num_envs), task, max_steps
        self.max_episode_steps = max_episode_steps
        h, w = resolution
        self._seed = env_kwargs.pop("seed", 0)
        env_kwargs.setdefault("copy", True)
        self._kwargs = dict(task=task, resolution=resolution, **env_kwargs)
        self._vec = VecEnv(self.num_envs, seed=self._seed, **self._kwargs)
        one = UmpnetEnv.spaces(h, w, obs_mode)
        self.single_observation_space, self.single_action_space = one
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        n = self.num_envs
        self._phase = np.zeros(n, np.int64)
        self._t = np.zeros(n, np.int64)  # direction steps
        self._env_steps = np.zeros(n, np.int64)  # all steps, for max_episode_steps
        self._done = np.zeros(n, bool)
        self._budget = np.full(n, 10, np.int64)
        self._start, self._farthest = np.zeros(n), np.zeros(n)
        self._limits, self._threshold, self._goal = np.zeros((n, 2)), np.zeros(n), np.zeros(n)
        self._joint = np.full(n, -1, np.int64)  # the grasped joint, -1 before a grasp

    def _observation(self, obs):
        state = None
        if self.obs_mode == "state":
            state = {
                "joints": self._vec.joint_positions(),
                "reference_joints": [obs_modes.reference_joints(s) for s in self._vec.scenes],
                "grasped_joint": self._joint.copy(),
            }
        return obs_modes.convert(self.obs_mode, obs, self._phase.copy(), obs["gripper_pixel"], state)

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._vec = VecEnv(self.num_envs, seed=int(seed), **self._kwargs)
        obs = self._vec.reset((options or {}).get("scenes"))
        n = self.num_envs
        self._phase[:], self._t[:], self._env_steps[:], self._done[:] = 0, 0, 0, False
        self._joint[:] = -1
        # The budgets come with the next step's info; until then, the scenes'.
        self._budget[:] = [BUDGETS.get(s.get("category"), 10) for s in self._vec.scenes]
        info = {"success": np.zeros(n, bool), "elapsed_steps": np.zeros(n, np.int64)}
        self._last = obs
        self._show()
        return self._observation(obs), info

    def step(self, actions):
        n = self.num_envs
        pixels = np.asarray(actions["pixel"], dtype=np.int64).reshape(n, 2)
        directions = np.asarray(actions["direction"], dtype=np.float32).reshape(n, 3)
        # Like UmpnetEnv: an unusable direction becomes straight up.
        bad = ~np.isfinite(directions).all(axis=1) | (np.linalg.norm(directions, axis=1) < 1e-6)
        directions = np.where(bad[:, None], np.array([0.0, 0.0, 1.0], np.float32), directions)
        reset = self._done.copy()
        obs, raw = self._vec.step_mixed(reset, self._phase.copy(), pixels, directions)
        kind = raw["kind"]
        reward = np.zeros(n)
        success = np.zeros(n, bool)
        terminated = np.zeros(n, bool)

        was_reset = kind == 1
        self._phase[was_reset], self._t[was_reset], self._env_steps[was_reset] = 0, 0, 0
        self._joint[was_reset] = -1
        self._budget[:] = raw["budget"]

        grasp = kind == 2
        self._phase[grasp] = 1
        self._joint[grasp] = raw["joint"][grasp]
        terminated[grasp] = ~raw["valid"][grasp]
        self._start[grasp], self._farthest[grasp] = raw["start"][grasp], 0.0
        self._limits[grasp], self._threshold[grasp] = raw["limits"][grasp], raw["threshold"][grasp]
        self._goal[grasp] = raw["goal"][grasp]

        # Nothing to do can only follow a lost grasp: the episode is over.
        terminated[kind == 0] = True
        move = kind == 3
        self._t[move] += 1
        r, ok, farthest = score(
            self.task,
            raw["joint_before"][move].astype(np.float64),
            raw["joint_after"][move].astype(np.float64),
            self._start[move],
            self._farthest[move],
            self._limits[move, 0],
            self._limits[move, 1],
            self._threshold[move],
            self._goal[move],
        )
        reward[move], success[move], terminated[move] = r, ok, ok
        self._farthest[move] = farthest

        self._env_steps[~was_reset] += 1
        budget = self._budget if self.max_steps is None else np.full(n, int(self.max_steps))
        truncated = ~terminated & ~was_reset & (self._t >= budget)
        if self.max_episode_steps is not None:
            truncated |= ~terminated & ~was_reset & (self._env_steps >= self.max_episode_steps)
        self._done = terminated | truncated
        info = {
            "success": success,
            "elapsed_steps": self._t.copy(),
            "reset": was_reset,
            **{k: raw[k] for k in ("valid", "joint", "joint_before", "joint_after", "r_dist", "aot", "suction_lost")},
        }
        self._last = obs
        self._show()
        return self._observation(obs), reward, terminated, truncated, info

    def _frames(self):
        if self.render_size is not None:
            return self._vec.render_rgb(*self.render_size)
        return rgb(self._last["image"])

    def _show(self):
        if self._viewer is not None:
            self._viewer.show(tile(self._frames()))

    def render(self):
        """Each environment's current colour image, (num_envs, H, W, 3) uint8,
        drawn again at ``render_size`` unless it is None. In human mode they
        are shown as one grid and this returns None."""
        if self._last is None:
            return None
        if self._viewer is not None:
            self._show()
            return None
        return self._frames()

    def close_extras(self, **kwargs):
        if self._viewer is not None:
            self._viewer.close()

    def __repr__(self):
        return f"UmpnetVectorEnv(num_envs={self.num_envs}, task={self.task!r})"


# The position step plus the largest budget: TimeLimit never cuts an episode
# short of its category's budget.
for _id, _task in (("umpnet/Explore-v0", "exploration"), ("umpnet/Goal-v0", "goal")):
    gym.register(
        id=_id,
        entry_point="umpnet.gym:UmpnetEnv",
        vector_entry_point="umpnet.gym:UmpnetVectorEnv",
        kwargs={"task": _task},
        max_episode_steps=MAX_BUDGET + 1,
    )
