"""Franka Kitchen's appliances (gymnasium-robotics' `kitchen_franka` scene) as
benchmark objects: which bodies of its scene file are appliances, and why
the others are left out. `python -m umpnet.objects franka-kitchen` uses it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

# The scene file, under a gymnasium_robotics package folder.
SCENE = Path("envs/assets/kitchen_franka/kitchen_assets/kitchen_env_model.xml")

# Body of the scene -> the object it becomes.
APPLIANCES = {"microwave": "microwave", "slidecabinet": "slidecabinet", "hingecabinet": "hingecabinet"}

# The scene's other articulated bodies, and why each is not an object here.
LEFT_OUT = {
    "ovenroot": "the stove's four knobs are mounted on a panel of another body (the back wall), "
    "so alone they float above it, and its burners slide 9 mm",
    "hoodroot": "its light switch is a few pixels at the benchmark's resolution: the oracle finds it "
    "in view in no goal scene",
    "kettle": "a free body (freejoint), not an articulated one",
    "panda": "the robot",
}


def scene_file(source: Path | None) -> Path:
    """The kitchen scene file: under `source` (a gymnasium_robotics package
    folder, or a folder that holds the scene file itself), else under the
    installed gymnasium_robotics package. FileNotFoundError says which and
    what was expected."""
    if source is None:
        spec = importlib.util.find_spec("gymnasium_robotics")
        if spec is None or not spec.submodule_search_locations:
            raise FileNotFoundError(
                "the gymnasium_robotics package is not installed: pip install gymnasium-robotics, "
                "or give --from with its unpacked wheel's gymnasium_robotics folder"
            )
        source = Path(next(iter(spec.submodule_search_locations)))
    for candidate in (source / SCENE, source / SCENE.name):
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(
        f"{source}: no {SCENE} (nor {SCENE.name}) in it; expected a gymnasium_robotics package folder"
    )
