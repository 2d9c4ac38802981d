"""Objects made elsewhere, brought into the PartNet-Mobility layout the simulator loads.

    python -m umpnet.objects import-mjcf FILE.xml --out DIR [--name NAME]
    python -m umpnet.objects metaworld --out data/external
    python -m umpnet.objects franka-kitchen --out data/kitchen

MJCF (MuJoCo's format: Meta-World, MuJoCo Menagerie, robosuite and LIBERO, dm_control)
is compiled by the official ``mujoco`` package, so defaults, classes,
includes, ``<compiler>`` settings, frames, orientations and mesh scales are
resolved by MuJoCo itself. The importer reads the compiled model at its
reference configuration (``qpos0``) and writes ``DIR/NAME/mobility.urdf``,
``textured_objs/*.obj`` with ``.mtl`` colours and ``object_meta_info.json``.

The mapping (docs/objects.md):
- hinge -> revolute (continuous when unlimited), slide -> prismatic, with
  MuJoCo's ranges measured from ``qpos0``; a body with several joints
  becomes a chain of helper links, as PartNet-Mobility writes them;
- free and ball joints, and bodies without joints, are fixed to their parent;
- top-level bodies whose subtree has no hinge or slide (tables, floors,
  walls, free objects) and planes are scenery and are left out;
- visual geoms (groups 0-2, not transparent) become meshes; collision-only
  geoms (groups 3-5) are skipped unless a part has nothing else to show.

Needs the ``mjcf`` extra (``pip install umpnet[mjcf]``); ``metaworld`` also
needs the ``metaworld`` extra.
"""

from .cli import main, metaworld_objects_dir
from .mjcf import (
    ANGLE_UNITS,
    BENCHMARK_DAMPING,
    BENCHMARK_FRICTION,
    DEFAULT_SIZE,
    Imported,
    ImportFailed,
    build,
    compile_mjcf,
)
from .urdf import import_folder, import_mjcf

__all__ = [
    "ANGLE_UNITS",
    "BENCHMARK_DAMPING",
    "BENCHMARK_FRICTION",
    "DEFAULT_SIZE",
    "ImportFailed",
    "Imported",
    "build",
    "compile_mjcf",
    "import_folder",
    "import_mjcf",
    "main",
    "metaworld_objects_dir",
]
