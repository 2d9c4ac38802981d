"""Reading an MJCF file: MuJoCo compiles it, and its articulated bodies
become links (meshes in the object frame at ``qpos0``) and joints."""

from __future__ import annotations

import contextlib
import math
import os
import re
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# MuJoCo's enums, by value (stable across 2.x-4.x).
_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3
_PLANE, _HFIELD, _SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = 0, 1, 2, 3, 4, 5, 6, 7
# MuJoCo's default geom rgba: a geom with this colour and a material shows the material's.
_DEFAULT_RGBA = np.array([0.5, 0.5, 0.5, 1.0])
# The viewer draws groups 0-2 by default; files put collision-only geoms in 3-5.
_VISUAL_GROUPS = range(3)
# robosuite's convention (GEOMTYPE2GROUP): 0 collision, 1 visual; its cameras
# draw group 1 unless asked to show collision meshes.
_ROBOSUITE_VISUAL_GROUPS = (1,)
# Joint dynamics of the generated objects (crates/sim/src/objects/builder.rs),
# so imported objects meet the same physics as the benchmark's own.
BENCHMARK_DAMPING = 2.0
BENCHMARK_FRICTION = 0.5
# Largest extent (m) of an imported object in the scene: the median largest
# extent of the generated objects at scene scale (docs/objects.md).
DEFAULT_SIZE = 0.8
# What the loader accepts (crates/sim/src/urdf/): limits within this many m or rad.
_MAX_LIMIT = 1000.0
_F32_MAX = float(np.finfo(np.float32).max)
_MIN_MESH_SCALE, _MAX_MESH_SCALE = 1e-6, 1e6
_MAX_LINKS = 64


class ImportFailed(Exception):
    """An MJCF file cannot become an object; the message names the file and why."""


@dataclass
class _Link:
    name: str
    origin: np.ndarray  # frame origin in the object frame (all link frames share its axes)
    visuals: list = field(default_factory=list)  # (vertices in the object frame, faces, rgba)


@dataclass
class _Joint:
    name: str
    kind: str
    parent: int
    child: int
    axis: np.ndarray
    lower: float
    upper: float
    damping: float
    friction: float


@dataclass
class Imported:
    """What one import wrote, for the caller's report."""

    name: str
    urdf: Path
    joints: list[tuple[str, str, float, float]]
    links: int
    dropped: list[str]
    warnings: list[str]
    scale: float


def _mujoco():
    try:
        import mujoco
    except ImportError as e:
        raise ImportFailed("the MJCF importer needs MuJoCo: pip install 'umpnet[mjcf]' (mujoco==3.3.0)") from e
    return mujoco


def _root_tag(path: Path) -> str:
    try:
        for _, elem in ET.iterparse(path, events=("start",)):
            return elem.tag
    except ET.ParseError as e:
        raise ImportFailed(f"{path}: not well-formed XML: {e}") from e
    return ""


ANGLE_UNITS = ("radian", "degree")


def compile_mjcf(path: Path, angle: str | None = None, robosuite: bool = False, warnings: list | None = None):
    """The compiled MjModel of ``path``. A ``<mujocoinclude>`` fragment is
    wrapped in a ``<mujoco>`` root beside it (so its relative paths resolve).
    ``angle`` ("radian" or "degree") is the unit of the file's angles, as a
    model that includes it declares (robosuite's objects are compiled inside
    one with ``<compiler angle="radian"/>``); None: the file's own, and
    MuJoCo's degrees where it says nothing. ``robosuite``: the file as
    robosuite includes an object ([`robosuite_object_xml`]); what that
    leaves out is appended to ``warnings``."""
    mujoco = _mujoco()
    if not path.is_file():
        raise ImportFailed(f"{path}: no such file")
    if angle is not None and angle not in ANGLE_UNITS:
        raise ImportFailed(f"--angle {angle}: expected one of {', '.join(ANGLE_UNITS)}")
    if robosuite:
        if angle is not None:
            raise ImportFailed(f"{path}: --robosuite reads angles in radians, as robosuite does; leave out --angle")
        return _compile_as_robosuite(mujoco, path, warnings if warnings is not None else [])
    if angle is not None and not hasattr(mujoco, "MjSpec"):
        raise ImportFailed(f"--angle needs MuJoCo 3.2 or newer (MjSpec); this is {mujoco.__version__}")

    def load(file: str):
        if angle is None:
            return mujoco.MjModel.from_xml_path(file)
        spec = mujoco.MjSpec.from_file(file)
        spec.compiler.degree = angle == "degree"
        return spec.compile()

    tag = _root_tag(path)
    if tag != "mujocoinclude":
        _check_raw(mujoco, path)
        try:
            return load(str(path))
        except Exception as e:  # MuJoCo raises ValueError; keep its words
            hint = (
                "; it has robosuite's object layout (a body named `object`): --robosuite reads it as robosuite does"
                if _has_robosuite_layout(path)
                else ""
            )
            raise ImportFailed(f"{path}: MuJoCo cannot compile it: {_one_line(e)}{hint}") from e
    # A fragment of bodies belongs in <worldbody>; one of assets or defaults in <mujoco>.
    include = f'<include file="{path.name}"/>'
    if _top_level_tags(path) & _WORLDBODY_CHILDREN:
        include = f"<worldbody>{include}</worldbody>"
    with _copy_beside(path, ".umpnet-wrap-", f'<mujoco model="{path.stem}">{include}</mujoco>\n') as wrapper:
        try:
            return load(wrapper)
        except Exception as e:
            raise ImportFailed(
                f"{path}: a <mujocoinclude> fragment that MuJoCo cannot compile inside a <mujoco> root: {_one_line(e)}"
            ) from e


@contextlib.contextmanager
def _copy_beside(path: Path, prefix: str, text: str):
    """``text`` in a temporary file beside ``path``, where MuJoCo resolves
    the file's relative paths from; removed afterwards."""
    try:
        fd, name = tempfile.mkstemp(prefix=prefix, suffix=".xml", dir=path.parent)
    except OSError as e:
        raise ImportFailed(
            f"{path}: cannot write a temporary file beside it ({e.strerror}), where MuJoCo resolves the "
            "file's relative paths from; copy its folder somewhere writable"
        ) from e
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        yield name
    finally:
        os.unlink(name)


_WORLDBODY_CHILDREN = {"body", "geom", "site", "camera", "light", "frame", "replicate"}
# <compiler> settings that say what robosuite's own compiler, and reading
# asset files beside the file, say anyway: not worth a warning.
_AS_ROBOSUITE_READS = {("angle", "radian")} | {
    (d, v) for d in ("meshdir", "texturedir", "assetdir") for v in ("", ".", "./")
}


def robosuite_object_xml(path: Path) -> tuple[str, list[str]]:
    """``path`` as robosuite's ``MujocoXMLObject`` (and LIBERO, which builds
    on it) puts an object into its scene, as one MJCF text, and what that
    left out: only the body named ``object`` (``./body/body`` or, as LIBERO
    also reads it, ``./body``), so the outer body's sites and annotations
    stay out; robosuite's ``<compiler angle="radian"/>`` instead of the
    file's own ``<compiler>``, which robosuite never merges (its inertia
    groups, its ``meshdir``: asset files are read relative to the file,
    where the caller writes this text); and of assets that share a tag and
    a name, the first, as robosuite merges them. [`build`] then draws the
    geoms robosuite's cameras draw: group 1, its visual group."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as e:
        raise ImportFailed(f"{path}: not well-formed XML: {e}") from e
    if root.tag != "mujoco":
        raise ImportFailed(f"{path}: --robosuite reads a <mujoco> file (a robosuite object), found <{root.tag}>")
    worldbody = root.find("worldbody")
    obj = _robosuite_object_body(worldbody)
    if worldbody is None or obj is None:
        raise ImportFailed(
            f"{path}: no body named `object` under <worldbody><body> (robosuite reads an object from "
            "./body/body[@name='object'])"
        )
    notes = []
    for c in root.findall("compiler"):
        differs = [f'{k}="{v}"' for k, v in c.attrib.items() if (k, v.strip()) not in _AS_ROBOSUITE_READS]
        if differs:
            notes.append(f"the file's <compiler {' '.join(differs)}> is not read, as robosuite does not")
        root.remove(c)
    root.insert(0, ET.Element("compiler", {"angle": "radian"}))
    seen = set()
    for asset in root.findall("asset"):
        for el in list(asset):
            key = (el.tag, el.get("name"))
            if key[1] is not None and key in seen:
                notes.append(f"{el.tag} `{key[1]}` is named twice: the first kept, as robosuite does")
                asset.remove(el)
                continue
            seen.add(key)
    for child in list(worldbody):
        worldbody.remove(child)
    worldbody.append(obj)
    return ET.tostring(root, encoding="unicode"), notes


def _robosuite_object_body(worldbody):
    """The body named ``object`` where robosuite's ``MujocoXMLObject`` reads
    it (``./body/body``), or where LIBERO also does (``./body``); None if
    neither holds one."""
    if worldbody is None:
        return None
    for where in ("./body/body[@name='object']", "./body[@name='object']"):
        obj = worldbody.find(where)
        if obj is not None:
            return obj
    return None


def _has_robosuite_layout(path: Path) -> bool:
    """Whether ``path`` holds its object where robosuite reads it."""
    try:
        return _robosuite_object_body(ET.parse(path).getroot().find("worldbody")) is not None
    except ET.ParseError:
        return False


def _compile_as_robosuite(mujoco, path: Path, warnings: list):
    text, notes = robosuite_object_xml(path)
    warnings.extend(notes)
    # Beside the file, so that its asset files resolve as robosuite resolves them.
    with _copy_beside(path, ".umpnet-robosuite-", text) as copy:
        try:
            _check_raw(mujoco, Path(copy))
        except ImportFailed as e:
            raise ImportFailed(str(e).replace(copy, str(path), 1)) from e
        try:
            return mujoco.MjModel.from_xml_path(copy)
        except Exception as e:  # MuJoCo raises ValueError; keep its words
            raise ImportFailed(f"{path}: MuJoCo cannot compile it as robosuite includes it: {_one_line(e)}") from e


def _top_level_tags(path: Path) -> set[str]:
    try:
        return {child.tag for child in ET.parse(path).getroot()}
    except ET.ParseError as e:
        raise ImportFailed(f"{path}: not well-formed XML: {e}") from e


def _check_raw(mujoco, path: Path) -> None:
    """Numbers as the file writes them (classes applied), before MuJoCo
    normalises an axis or turns a mesh scale into a compile error: the same
    bounds as the URDF loader's, naming the element."""
    if not hasattr(mujoco, "MjSpec"):
        return
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError:
        return  # MuJoCo's compile error says it better
    limited = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
    for j in spec.joints:
        if j.type not in limited:
            continue
        _check_number(path, f"joint `{j.name}` axis", list(j.axis))
        _check_number(path, f"joint `{j.name}` range", list(j.range))
        # A hinge's range may be in degrees here; build() bounds it in radians.
        slide = j.type == mujoco.mjtJoint.mjJNT_SLIDE
        if slide and max(abs(v) for v in j.range) > _MAX_LIMIT:
            raise ImportFailed(
                f"{path}: joint `{j.name}` range {list(map(float, j.range))} is beyond "
                f"±{_MAX_LIMIT:g} (m or rad); a joint without limits leaves range unset"
            )
    for m in spec.meshes:
        scale = [float(v) for v in m.scale]
        if not all(_MIN_MESH_SCALE <= abs(v) <= _MAX_MESH_SCALE for v in scale):
            raise ImportFailed(
                f"{path}: mesh `{m.name}` scale must be within "
                f"[{_MIN_MESH_SCALE:g}, {_MAX_MESH_SCALE:g}] in size, found {scale}"
            )


def _one_line(e: Exception) -> str:
    return " ".join(str(e).split())


# --- geometry -----------------------------------------------------------------


def _lathe(profile: list[tuple[float, float]], segments: int = 24):
    """A surface of revolution about z from (radius, z) points, bottom to top;
    a zero radius closes the surface there."""
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    verts, rings = [], []
    for r, z in profile:
        if r <= 1e-12:
            rings.append([len(verts)])
            verts.append((0.0, 0.0, z))
        else:
            start = len(verts)
            verts.extend((r * math.cos(a), r * math.sin(a), z) for a in angles)
            rings.append(list(range(start, start + segments)))
    faces = []
    for i in range(len(rings) - 1):
        lo, hi = rings[i], rings[i + 1]
        for k in range(segments):
            a0, a1 = lo[k % len(lo)], lo[(k + 1) % len(lo)]
            b0, b1 = hi[k % len(hi)], hi[(k + 1) % len(hi)]
            if len(lo) > 1:
                faces.append((a0, a1, b1 if len(hi) > 1 else b0))
            if len(hi) > 1:
                faces.append((a0, b1, b0))
    return np.array(verts, dtype=np.float64), np.array(faces, dtype=np.int64)


def _sphere_profile(radius: float, z_low: float, z_high: float, rings: int = 12):
    """Bottom hemisphere centred at z_low, top hemisphere at z_high."""
    half = rings // 2
    lower = [(-math.pi / 2 + math.pi / 2 * k / half) for k in range(half + 1)]
    upper = [(math.pi / 2 * k / half) for k in range(half + 1)]
    prof = [(radius * math.cos(t), z_low + radius * math.sin(t)) for t in lower]
    top = [(radius * math.cos(t), z_high + radius * math.sin(t)) for t in upper]
    if z_high == z_low:
        top = top[1:]
    return prof + top


def _box(half):
    x, y, z = half
    v = np.array(
        [[sx * x, sy * y, sz * z] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
        dtype=np.float64,
    )
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    f = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(f, dtype=np.int64)


def _geom_mesh(m, g: int):
    """Vertices (geom frame) and faces of geom g, or None for a shape with no surface to draw."""
    t, size = int(m.geom_type[g]), m.geom_size[g]
    if t == _MESH:
        mid = int(m.geom_dataid[g])
        va, vn = int(m.mesh_vertadr[mid]), int(m.mesh_vertnum[mid])
        fa, fn = int(m.mesh_faceadr[mid]), int(m.mesh_facenum[mid])
        return np.array(m.mesh_vert[va : va + vn], dtype=np.float64), np.array(
            m.mesh_face[fa : fa + fn], dtype=np.int64
        )
    if t == _BOX:
        return _box(size[:3])
    if t == _SPHERE:
        return _lathe(_sphere_profile(size[0], 0.0, 0.0))
    if t == _ELLIPSOID:
        v, f = _lathe(_sphere_profile(1.0, 0.0, 0.0))
        return v * np.asarray(size[:3]), f
    if t == _CAPSULE:
        return _lathe(_sphere_profile(size[0], -size[1], size[1]))
    if t == _CYLINDER:
        r, h = size[0], size[1]
        return _lathe([(0.0, -h), (r, -h), (r, h), (0.0, h)])
    return None  # plane, height field, SDF: scenery or nothing a camera sees


def _texture_mean(m, tex: int) -> np.ndarray | None:
    """The mean colour of a texture (the renderer has no textures; this is their tint)."""
    if tex < 0 or tex >= m.ntex:
        return None
    n = int(m.tex_nchannel[tex]) if hasattr(m, "tex_nchannel") else 3
    adr, h, w = int(m.tex_adr[tex]), int(m.tex_height[tex]), int(m.tex_width[tex])
    data = np.asarray(m.tex_data[adr : adr + h * w * n], dtype=np.float64).reshape(-1, n)
    if len(data) == 0 or n < 3:
        return None
    return data[:, :3].mean(axis=0) / 255.0


def _geom_rgba(m, g: int) -> np.ndarray:
    """What MuJoCo draws: the geom's rgba, or its material's when the geom keeps
    the default, tinted by the material's texture."""
    rgba = np.array(m.geom_rgba[g], dtype=np.float64)
    mat = int(m.geom_matid[g])
    if mat >= 0 and np.allclose(rgba, _DEFAULT_RGBA):
        rgba = np.array(m.mat_rgba[mat], dtype=np.float64)
        texids = np.atleast_1d(np.asarray(m.mat_texid[mat]))
        tex = next((int(t) for t in texids if int(t) >= 0), -1)
        tint = _texture_mean(m, tex)
        if tint is not None:
            rgba[:3] *= tint
    return np.clip(rgba, 0.0, 1.0)


# --- the model ----------------------------------------------------------------


def _name(m, kind: str, i: int) -> str:
    mujoco = _mujoco()
    obj = {"body": mujoco.mjtObj.mjOBJ_BODY, "joint": mujoco.mjtObj.mjOBJ_JOINT}[kind]
    return mujoco.mj_id2name(m, obj, i) or f"{kind}{i}"


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "x"


def _check_number(path: Path, what: str, values) -> None:
    flat = np.asarray(values, dtype=np.float64).ravel()
    bad = flat[~(np.isfinite(flat) & (np.abs(flat) <= _F32_MAX))]
    if bad.size:
        raise ImportFailed(f"{path}: {what} must be finite within f32 range, found {float(bad[0])!r}")


def _ancestors(m, b: int) -> list[int]:
    out = []
    while b > 0:
        b = int(m.body_parentid[b])
        out.append(b)
    return out


def build(
    path: Path,
    dynamics: str = "benchmark",
    body: str | None = None,
    angle: str | None = None,
    robosuite: bool = False,
):
    """The object of an MJCF file as links and joints in the object frame at
    qpos0: every top-level subtree with a hinge or slide joint, or only the
    subtree of the named ``body`` (one appliance out of a scene); ``angle``
    and ``robosuite`` as [`compile_mjcf`] takes them."""
    mujoco = _mujoco()
    dropped, warnings = [], []
    m = compile_mjcf(path, angle, robosuite, warnings)
    d = mujoco.MjData(m)
    d.qpos[:] = m.qpos0
    mujoco.mj_kinematics(m, d)

    movable = [j for j in range(m.njnt) if int(m.jnt_type[j]) in (_SLIDE, _HINGE)]
    root = 0
    if body is not None:
        root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, body)
        if root < 0:
            named = sorted(
                {
                    _name(m, "body", a)
                    for j in movable
                    for a in [int(m.jnt_bodyid[j]), *_ancestors(m, int(m.jnt_bodyid[j]))]
                    if a > 0 and mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, a)
                }
            )
            raise ImportFailed(
                f"{path}: no body named `{body}`; bodies with hinge or slide joints in them or "
                f"below them: {', '.join(named) or 'none'}"
            )
        movable = [j for j in movable if root in (int(m.jnt_bodyid[j]), *_ancestors(m, int(m.jnt_bodyid[j])))]
    if not movable:
        kinds = sorted({("free", "ball", "slide", "hinge")[int(t)] for t in m.jnt_type})
        found = f"only {', '.join(kinds)} joints" if kinds else "no joints"
        where = f" in body `{body}`" if body else ""
        raise ImportFailed(f"{path}: no hinge or slide joint{where} ({found}); an articulated object needs one")
    articulated_roots = {int(m.body_rootid[int(m.jnt_bodyid[j])]) for j in movable}

    links = [_Link("base", np.zeros(3))]
    joints: list[_Joint] = []
    # body -> link that carries it; with a named body, its parent stands for the base.
    owner = {0: 0} if body is None else {int(m.body_parentid[root]): 0}
    for b in range(1, m.nbody):
        if body is not None:
            if b != root and root not in _ancestors(m, b):
                continue
        elif int(m.body_rootid[b]) not in articulated_roots:
            if int(m.body_parentid[b]) == 0:
                dropped.append(_name(m, "body", b))
            continue
        cur = owner[int(m.body_parentid[b])]
        adr, num = int(m.body_jntadr[b]), int(m.body_jntnum[b])
        body_joints = [j for j in range(adr, adr + num) if int(m.jnt_type[j]) in (_SLIDE, _HINGE)]
        for k, j in enumerate(body_joints):
            jname = _name(m, "joint", j)
            anchor = np.array(d.xanchor[j], dtype=np.float64)
            axis = np.array(d.xaxis[j], dtype=np.float64)
            _check_number(path, f"joint `{jname}` position", anchor)
            _check_number(path, f"joint `{jname}` axis", axis)
            prismatic = int(m.jnt_type[j]) == _SLIDE
            q0 = float(m.qpos0[int(m.jnt_qposadr[j])])
            lo, hi = (float(v) - q0 for v in m.jnt_range[j])
            limited = bool(m.jnt_limited[j]) and lo < hi
            if limited and max(abs(lo), abs(hi)) > _MAX_LIMIT:
                unit = "m" if prismatic else "rad"
                raise ImportFailed(
                    f"{path}: joint `{jname}` range [{lo:g}, {hi:g}] {unit} is beyond "
                    f"±{_MAX_LIMIT:g}; no object moves that far"
                )
            if prismatic and not limited:
                warnings.append(f"slide `{jname}` has no range: fixed")
                continue
            kind = ("prismatic" if prismatic else "revolute") if limited else "continuous"
            if float(m.jnt_stiffness[j]) > 0:
                warnings.append(f"joint `{jname}`: its spring (stiffness) is not simulated")
            dof = int(m.jnt_dofadr[j])
            if dynamics == "file":
                damping, friction = float(m.dof_damping[dof]), float(m.dof_frictionloss[dof])
            else:
                damping, friction = BENCHMARK_DAMPING, BENCHMARK_FRICTION
            last = k == len(body_joints) - 1
            lname = _safe(_name(m, "body", b)) if last else f"{_safe(_name(m, 'body', b))}_{k}"
            links.append(_Link(lname, anchor))
            child = len(links) - 1
            joints.append(_Joint(_safe(jname), kind, cur, child, axis, lo, hi, damping, friction))
            cur = child
        owner[b] = cur
    if len(links) > _MAX_LINKS:
        raise ImportFailed(f"{path}: {len(links)} links after import; an object may have at most {_MAX_LINKS}")

    # Geometry: what a viewer draws, by the link that carries its body.
    visual_groups = _ROBOSUITE_VISUAL_GROUPS if robosuite else _VISUAL_GROUPS
    shown: dict[int, list[int]] = {}
    hidden: dict[int, list[int]] = {}
    for g in range(m.ngeom):
        b = int(m.geom_bodyid[g])
        # With a named body, its parent's geoms are the scene around it, not the object.
        if b not in owner or (body is not None and b == int(m.body_parentid[root])):
            continue
        if b == 0 and int(m.geom_type[g]) in (_PLANE, _HFIELD):
            continue
        link = owner[b]
        visible = int(m.geom_group[g]) in visual_groups and _geom_rgba(m, g)[3] > 0.0
        (shown if visible else hidden).setdefault(link, []).append(g)
    for link in range(len(links)):
        geoms = shown.get(link) or hidden.get(link, [])
        # Hidden geoms drawn for want of visible ones are drawn opaque.
        opaque = link not in shown
        if link in hidden and link not in shown and link > 0:
            warnings.append(f"link `{links[link].name}` has only collision geoms: drawn from those")
        for g in geoms:
            mesh = _geom_mesh(m, g)
            if mesh is None or len(mesh[1]) == 0:
                continue
            v, f = mesh
            rot = np.array(d.geom_xmat[g], dtype=np.float64).reshape(3, 3)
            v_in_object = v @ rot.T + np.array(d.geom_xpos[g], dtype=np.float64)
            _check_number(path, f"geom {g} vertices", v_in_object)
            rgba = _geom_rgba(m, g)
            if opaque:
                rgba[3] = 1.0
            links[link].visuals.append((v_in_object, f, rgba))
    return links, joints, dropped, warnings
