"""``umpnet.Policy``: the Rust policy runtime, with ``act`` for gymnasium."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import numpy as np

from ._umpnet import Policy as _Policy
from ._umpnet import onnxruntime_in_site_packages

# The shipped model package: inside the wheel, or a link to models/umpnet-gpu-medium
# in a source checkout.
SHIPPED_MODEL = Path(__file__).with_name("model")


def onnxruntime_library() -> Path | None:
    """The ONNX Runtime shared library of this interpreter's ``onnxruntime``
    package (found without importing it), or None. Looked up here because the
    runtime's own search asks ``python3`` on PATH, which need not be the
    interpreter this module runs in (a venv used without activating it)."""
    spec = importlib.util.find_spec("onnxruntime")
    if spec is None or not spec.submodule_search_locations:
        return None
    for root in spec.submodule_search_locations:
        # Which file in the package is the Rust runtime's rule, as for its own searches.
        library = onnxruntime_in_site_packages(Path(root).parent)
        if library is not None:
            return Path(library)
    return None


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

    ONNX Runtime is the ``onnxruntime`` package's library unless
    ``onnxruntime`` (a path to ``libonnxruntime.so.1.*``) or the
    ``ORT_DYLIB_PATH`` environment variable names another. The library is
    loaded once per process: the first Policy's choice holds.
    ``direction_filter`` replaces the package's (``none``, ``normal90``,
    ``prev90``, ``joint45``, ``goal45`` or ``onward45``), as ``--direction-filter`` does
    on the command line; ``grasp_rule`` replaces the package's ``grasp``
    (``affordance``, the paper's, ``affordance_times_movable`` or
    ``affordance_times_movable_lever``), as ``--grasp-rule`` does;
    ``mirror_average=True`` scores every candidate also on the scene mirrored
    left-right and acts on the mean, as ``--mirror-average`` does.
    """

    def __new__(
        cls,
        model_dir,
        seed: int = 0,
        threads: int = 1,
        onnxruntime=None,
        direction_filter=None,
        grasp_rule=None,
        mirror_average: bool = False,
    ):
        if onnxruntime is None and "ORT_DYLIB_PATH" not in os.environ:
            onnxruntime = onnxruntime_library()
        return super().__new__(
            cls,
            os.fspath(model_dir),
            seed,
            threads,
            None if onnxruntime is None else os.fspath(onnxruntime),
            direction_filter,
            grasp_rule,
            mirror_average,
        )

    @classmethod
    def default(
        cls,
        seed: int = 0,
        threads: int = 1,
        direction_filter: str | None = None,
        grasp_rule: str | None = None,
        mirror_average: bool = False,
    ) -> Policy:
        """The shipped model package (``umpnet-gpu-medium``), as installed with the wheel."""
        if not (SHIPPED_MODEL / "model.json").is_file():
            raise FileNotFoundError(
                f"the shipped model is not at {SHIPPED_MODEL}: this install of umpnet was built without it"
            )
        return cls(
            SHIPPED_MODEL,
            seed=seed,
            threads=threads,
            direction_filter=direction_filter,
            grasp_rule=grasp_rule,
            mirror_average=mirror_average,
        )

    def act(self, obs: dict, task: str = "exploration", info: dict | None = None) -> dict:
        """The gym action for ``obs``: the grasp pixel in phase 0, then a
        direction (straight up when the policy stops, which the environment
        takes as a move that ends nothing). ``task`` is ``exploration`` or
        ``goal``; toward a goal, the grasp and every direction read
        ``obs["reference"]`` as the goal observation.

        Pass the last step's ``info`` and the policy decides as ``umpnet
        eval`` does: a move that moved nothing (``info["moved"]``) is not
        tried again until one does, and the ``goal45`` and ``onward45``
        filters read how the gripper went (``info["gripper_in_world"]``). With ``reset(seed)`` at each episode's
        start, and the benchmark's scene and seed, it makes the benchmark's
        moves (``umpnet.benchmark_seeds`` gives them). When the policy
        stops (no candidate it expects to help), ``self.stopped`` is True
        and the action is straight up; ``umpnet eval`` ends the episode there."""
        if task not in ("exploration", "goal"):
            raise ValueError(f"task {task!r}: expected 'exploration' or 'goal'")
        image = np.asarray(obs["image"], np.float32)
        reference = np.asarray(obs["reference"], np.float32)
        self.stopped = False
        if int(np.asarray(obs["phase"])) == 0:
            self.reset()  # a new grasp: nothing banned yet
            row, col = self.position(image, reference if task == "goal" else None)
            return {"phase": 0, "pixel": np.array([row, col], np.int64), "direction": np.zeros(3, np.float32)}
        row, col = (int(v) for v in np.asarray(obs["gripper_pixel"]).reshape(2))
        moved = None if info is None or "moved" not in info else bool(info["moved"])
        gripper = None if info is None else info.get("gripper_in_world")
        mode = "goal" if task == "goal" else "explore"
        decision = self.decide(image, reference, (row, col), mode, moved, gripper)
        self.stopped = decision["direction"] is None
        direction = [0.0, 0.0, 1.0] if self.stopped else decision["direction"]
        return {"phase": 1, "pixel": np.zeros(2, np.int64), "direction": np.asarray(direction, np.float32)}
