"""``python -m umpnet.objects``: import one file, a folder, Meta-World's
objects or Franka Kitchen's appliances, and report what was written."""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
from pathlib import Path

from .mjcf import ANGLE_UNITS, DEFAULT_SIZE, Imported, ImportFailed
from .urdf import import_folder, import_mjcf


def metaworld_objects_dir() -> Path:
    spec = importlib.util.find_spec("metaworld")
    if spec is None or not spec.submodule_search_locations:
        raise ImportFailed("the metaworld package is not installed: pip install 'umpnet[metaworld]'")
    return Path(next(iter(spec.submodule_search_locations))) / "assets" / "objects"


def _report(imported: list[Imported], skipped, as_json: bool) -> None:
    if as_json:
        print(
            json.dumps(
                {
                    "imported": [
                        {
                            "name": i.name,
                            "urdf": str(i.urdf),
                            "joints": [{"name": n, "type": k, "lower": lo, "upper": hi} for n, k, lo, hi in i.joints],
                            "links": i.links,
                            "scale": i.scale,
                            "dropped": i.dropped,
                            "warnings": i.warnings,
                        }
                        for i in imported
                    ],
                    "skipped": [{"file": f, "why": why} for f, why in skipped],
                }
            )
        )
        return
    for i in imported:
        kinds = ", ".join(f"{k} {n} [{lo:.3g}, {hi:.3g}]" for n, k, lo, hi in i.joints)
        print(f"{i.name}: {i.links} links; {kinds}; scale {i.scale:.3f} -> {i.urdf}")
        if i.dropped:
            print(f"  left out as scenery: {', '.join(i.dropped)}")
        for w in i.warnings:
            print(f"  warning: {w}")
    for f, why in skipped:
        print(f"skipped {f}: {why}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m umpnet.objects", description=sys.modules[__package__].__doc__.split("\n")[0]
    )
    sub = p.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--out", type=Path, required=True, help="folder to write NAME/ into")
    common.add_argument(
        "--size",
        type=float,
        default=DEFAULT_SIZE,
        help=f"largest extent in the scene, metres (default {DEFAULT_SIZE}, as generated objects)",
    )
    common.add_argument(
        "--dynamics",
        choices=["benchmark", "file"],
        default="benchmark",
        help="joint damping/friction: the generated objects' (default) or the file's",
    )
    common.add_argument("--force", action="store_true", help="replace an object already in --out")
    common.add_argument("--json", action="store_true", help="print what was done as JSON")
    placing = argparse.ArgumentParser(add_help=False)
    placing.add_argument("--yaw", type=float, default=0.0, help="turn the object about z (degrees) to face -y")
    including = placing.add_mutually_exclusive_group()
    including.add_argument(
        "--angle",
        choices=ANGLE_UNITS,
        help="the unit of the file's angles where the model that includes it sets it "
        "(robosuite's objects: radian, from its <compiler angle=\"radian\"/>); default: the file's own, "
        "MuJoCo's degrees where it says nothing",
    )
    including.add_argument(
        "--robosuite",
        action="store_true",
        help="read the file as robosuite (and LIBERO) include an object: only its body named `object`, "
        "robosuite's <compiler angle=\"radian\"/> instead of the file's own, asset files relative to the file, "
        "the first of assets that share a name",
    )
    one = sub.add_parser("import-mjcf", parents=[common, placing], help="import one MJCF file")
    one.add_argument("file", type=Path, help="an MJCF file, or a <mujocoinclude> fragment")
    one.add_argument("--name", help="the object's folder name (default: --body, else the file's stem)")
    one.add_argument("--body", help="import only this body's subtree (one appliance out of a scene file)")
    folder = sub.add_parser(
        "import-folder",
        parents=[common, placing],
        help="import every articulated object among the MJCF files directly in a folder "
        "(e.g. robosuite's models/assets/objects with --robosuite --yaw 90, LIBERO's articulated_objects with --robosuite)",
    )
    folder.add_argument("folder", type=Path, help="a folder of MJCF files; the others are skipped with the reason")
    sub.add_parser(
        "metaworld",
        parents=[common],
        help="import every articulated object of the installed metaworld package",
    )
    kitchen = sub.add_parser(
        "franka-kitchen",
        parents=[common],
        help="import Franka Kitchen's microwave and sliding and hinged cabinets (gymnasium-robotics)",
    )
    kitchen.add_argument(
        "--from",
        dest="source",
        type=Path,
        help="a gymnasium_robotics package folder (e.g. from its unpacked wheel); default: the installed package",
    )
    a = p.parse_args(argv)
    kw = {"size": a.size, "dynamics": a.dynamics, "force": a.force}
    try:
        if a.command == "import-mjcf":
            imported = [
                import_mjcf(
                    a.file, a.out, a.name, yaw_deg=a.yaw, body=a.body, angle=a.angle, robosuite=a.robosuite, **kw
                )
            ]
            skipped = []
        elif a.command == "import-folder":
            if not a.folder.is_dir():
                raise ImportFailed(f"{a.folder}: no such folder")
            imported, skipped = import_folder(
                a.folder, a.out, yaw_deg=a.yaw, angle=a.angle, robosuite=a.robosuite, **kw
            )
            if not imported:
                raise ImportFailed(f"{a.folder}: no articulated object among its {len(skipped)} MJCF files")
        elif a.command == "franka-kitchen":
            from . import kitchen

            try:
                scene = kitchen.scene_file(a.source)
            except FileNotFoundError as e:
                raise ImportFailed(str(e)) from e
            imported = [import_mjcf(scene, a.out, name, body=body, **kw) for body, name in kitchen.APPLIANCES.items()]
            skipped = list(kitchen.LEFT_OUT.items())
        else:
            imported, skipped = import_folder(metaworld_objects_dir(), a.out, **kw)
            if not imported:
                raise ImportFailed("no articulated object found in the metaworld package")
    except ImportFailed as e:
        if a.json:
            print(json.dumps({"error": str(e)}))
        print(f"error: {e}", file=sys.stderr)
        return 1
    _report(imported, skipped, a.json)
    return 0
