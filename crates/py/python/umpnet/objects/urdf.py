"""Writing an object read from MJCF in the PartNet-Mobility layout:
``mobility.urdf``, ``textured_objs/*.obj`` and ``object_meta_info.json``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .mjcf import DEFAULT_SIZE, Imported, ImportFailed, _Link, _one_line, _safe, build


def _bounds(links: list[_Link]):
    pts = [v for link in links for (v, _, _) in link.visuals]
    if not pts:
        return None
    allp = np.concatenate(pts)
    return allp.min(axis=0), allp.max(axis=0)


def _write_obj(path: Path, verts: np.ndarray, faces: np.ndarray, rgb, material: str) -> None:
    mtl = path.with_suffix(".mtl")
    mtl.write_text(f"newmtl {material}\nKd {rgb[0]:.4f} {rgb[1]:.4f} {rgb[2]:.4f}\n")
    lines = [f"mtllib {mtl.name}", f"usemtl {material}"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def _glass(rgba, k: int) -> str:
    """A translucent geom's alpha as a URDF material (the loader draws it as
    glass; the colour stays the MTL's); nothing for an opaque one."""
    r, g, b, a = (float(c) for c in rgba)
    if a >= 1.0:
        return ""
    return f'      <material name="m{k}"><color rgba="{r:.4f} {g:.4f} {b:.4f} {a:.4f}"/></material>\n'


def _inertial(link: _Link) -> str:
    """1 kg with the inertia of its geometry's bounding box at the box's centre:
    the convention of the generated objects (PyBullet's mass for PartNet's
    inertia-less links), so imported parts weigh what the benchmark's do."""
    b = _bounds([link])
    lo, hi = b if b else (link.origin - 0.025, link.origin + 0.025)
    size = np.maximum(hi - lo, 0.005)
    com = (lo + hi) / 2 - link.origin
    sx, sy, sz = size
    ix, iy, iz = (sy**2 + sz**2) / 12, (sx**2 + sz**2) / 12, (sx**2 + sy**2) / 12
    return (
        f'    <inertial>\n      <origin xyz="{com[0]:.6f} {com[1]:.6f} {com[2]:.6f}" rpy="0 0 0"/>\n'
        f'      <mass value="1"/>\n      <inertia ixx="{ix:.8f}" ixy="0" ixz="0" iyy="{iy:.8f}" '
        f'iyz="0" izz="{iz:.8f}"/>\n    </inertial>\n'
    )


def import_mjcf(
    path: Path,
    out: Path,
    name: str | None = None,
    size: float = DEFAULT_SIZE,
    yaw_deg: float = 0.0,
    dynamics: str = "benchmark",
    force: bool = False,
    body: str | None = None,
    angle: str | None = None,
    robosuite: bool = False,
) -> Imported:
    """Imports one MJCF file to ``out/NAME`` (NAME: the file's stem by
    default); ``angle``: the unit of its angles where a model that includes
    it sets it; ``robosuite``: the file as robosuite includes an object
    ([`compile_mjcf`])."""
    path = Path(path)
    name = _safe(name or body or path.stem)
    if not (math.isfinite(size) and 0.01 <= size <= 100.0):
        raise ImportFailed(f"--size {size}: expected metres in [0.01, 100]")
    if not (math.isfinite(yaw_deg) and -360.0 <= yaw_deg <= 360.0):
        raise ImportFailed(f"--yaw {yaw_deg}: expected degrees in [-360, 360]")
    links, joints, dropped, warnings = build(path, dynamics, body, angle, robosuite)
    bounds = _bounds(links)
    if bounds is None:
        raise ImportFailed(f"{path}: no visible geometry on the articulated bodies")
    lo, hi = bounds
    extent = float((hi - lo).max())
    if not extent > 0:
        raise ImportFailed(f"{path}: the object's geometry has no extent")
    if not any(links[j.child].visuals for j in joints) and not any(links[c].visuals for c in range(1, len(links))):
        warnings.append("no moving part has visible geometry")
    # The object frame: centred in x and y on the floor (z = 0 at its lowest point).
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    links[0].origin = centre

    dest = Path(out) / name
    if dest.exists() and not force:
        raise ImportFailed(f"{dest} exists; pass --force to replace it")
    objs = dest / "textured_objs"
    objs.mkdir(parents=True, exist_ok=True)
    for stale in objs.glob("original-*"):
        stale.unlink()

    xml = [f'<?xml version="1.0"?>\n<robot name="{name}">']
    k = 0
    for link in links:
        parts = [f'  <link name="{link.name}">\n', _inertial(link)]
        for verts, faces, rgba in link.visuals:
            file = f"textured_objs/original-{k}.obj"
            _write_obj(dest / file, verts - link.origin, faces, rgba[:3], f"m{k}")
            geom = f'<geometry><mesh filename="{file}"/></geometry>'
            parts.append(
                f'    <visual>\n      <origin xyz="0 0 0" rpy="0 0 0"/>\n      {geom}\n{_glass(rgba, k)}    </visual>\n'
                f'    <collision>\n      <origin xyz="0 0 0" rpy="0 0 0"/>\n      {geom}\n'
                f"    </collision>\n"
            )
            k += 1
        parts.append("  </link>")
        xml.append("".join(parts))
    for j in joints:
        o = links[j.child].origin - links[j.parent].origin
        limit = (
            f'    <limit lower="{j.lower:.6f}" upper="{j.upper:.6f}" effort="100" velocity="1"/>\n'
            if j.kind != "continuous"
            else ""
        )
        xml.append(
            f'  <joint name="{j.name}" type="{j.kind}">\n'
            f'    <origin xyz="{o[0]:.6f} {o[1]:.6f} {o[2]:.6f}" rpy="0 0 0"/>\n'
            f'    <axis xyz="{j.axis[0]:.6f} {j.axis[1]:.6f} {j.axis[2]:.6f}"/>\n'
            f'    <parent link="{links[j.parent].name}"/>\n    <child link="{links[j.child].name}"/>\n'
            f"{limit}"
            f'    <dynamics damping="{j.damping:g}" friction="{j.friction:g}"/>\n  </joint>'
        )
    xml.append("</robot>\n")
    urdf = dest / "mobility.urdf"
    urdf.write_text("\n".join(xml))

    scale = size / extent
    half = math.radians(yaw_deg) / 2
    meta = {
        "orientation": [0.0, 0.0, math.sin(half), math.cos(half)],
        "offset_z": 0.0,
        "scale": scale,
        "moveable_link": {},
        "source": {"format": "mjcf", "file": str(path), "importer": "umpnet.objects"},
    }
    if angle is not None:
        meta["source"]["angle"] = angle
    if robosuite:
        meta["source"]["included_as"] = "robosuite"
    (dest / "object_meta_info.json").write_text(json.dumps(meta, indent=2) + "\n")
    _check_loads(urdf, scale)
    return Imported(
        name=name,
        urdf=urdf,
        joints=[(j.name, j.kind, j.lower, j.upper) for j in joints],
        links=len(links),
        dropped=dropped,
        warnings=warnings,
        scale=scale,
    )


def _check_loads(urdf: Path, scale: float) -> None:
    """The written object must pass the simulator's own loader checks."""
    try:
        from .._umpnet import Articulation
    except ImportError:  # the pure-Python parts alone (no native module built)
        return
    try:
        Articulation(str(urdf), scale=scale)
    except Exception as e:
        raise ImportFailed(f"{urdf}: written, but the simulator refuses it: {_one_line(e)}") from e


def import_folder(src: Path, out: Path, **kw) -> tuple[list[Imported], list[tuple[str, str]]]:
    """Every ``*.xml`` directly in ``src`` that compiles to an articulated object."""
    done, skipped = [], []
    for f in sorted(src.glob("*.xml")):
        try:
            done.append(import_mjcf(f, out, **kw))
        except ImportFailed as e:
            skipped.append((f.name, str(e).removeprefix(f"{f}: ")))
    return done, skipped
