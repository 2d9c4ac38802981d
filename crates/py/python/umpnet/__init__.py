"""umpnet: the UMPNet simulator and policy runtime (Rust), from Python.

- ``Env``: one simulated scene; ``reset``, ``step_position(row, col)``,
  ``step_direction(xyz)``; observations are dicts of numpy arrays.
- ``VecEnv``: n environments stepped in parallel Rust threads.
- ``Policy``: the Rust policy runtime on an exported model package.
- ``Articulation``: the physics of one URDF object (grasp at a world point,
  move the gripper), under the ``reference`` or ``ideal`` profile.
- ``categories()``: (name, split, step budget) of the 22 object categories.
- ``umpnet.gym``: a gymnasium wrapper (optional; needs gymnasium).
"""

from ._umpnet import Articulation, Env, Policy, VecEnv, __version__, categories

__all__ = ["Articulation", "Env", "Policy", "VecEnv", "__version__", "categories"]
