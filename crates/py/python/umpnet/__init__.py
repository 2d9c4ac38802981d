"""umpnet: the UMPNet simulator and policy runtime (Rust), from Python.

- ``Env``: one simulated scene; ``reset``, ``step_position(row, col)``,
  ``step_direction(xyz)``; observations are dicts of numpy arrays.
- ``VecEnv``: n environments stepped in parallel Rust threads.
- ``EnvConfig``: what scenes they sample (categories or an object file with
  its ``scale``/``pose``, split, task, resolution, renderer, physics), given
  as ``config=`` or as its keyword arguments to either.
- ``Policy``: the Rust policy runtime on an exported model package;
  ``Policy.act(obs, task)`` drives ``umpnet.gym``'s environments.
- ``Articulation``: the physics of one URDF object (grasp at a world point,
  move the gripper), under the ``reference`` or ``ideal`` profile.
- ``categories()``: (name, split, step budget) of the 22 object categories.
- ``umpnet.gym``: a gymnasium wrapper (optional; needs gymnasium).
"""

import os
import tempfile

# The Vulkan loader warns on headless machines without it. Set here, at
# import, from Python: the Rust library never writes the environment, which
# is unsound once other threads run.
os.environ.setdefault("XDG_RUNTIME_DIR", tempfile.gettempdir())

from ._umpnet import Articulation, Env, EnvConfig, VecEnv, __version__, benchmark_seeds, categories
from .policy import Policy

__all__ = [
    "Articulation",
    "Env",
    "EnvConfig",
    "Policy",
    "VecEnv",
    "__version__",
    "benchmark_seeds",
    "categories",
]
