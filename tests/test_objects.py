"""Objects made elsewhere: the MJCF importer (`python -m umpnet.objects`, through
MuJoCo) and `umpnet eval --objects`, on Meta-World's objects and on MJCF files
written here."""

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import umpnet
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
UMPNET = os.environ.get("UMPNET_BIN", str(ROOT / "target" / "release" / "umpnet"))
CABINET = ROOT / "tests" / "data" / "mjcf" / "two_door_cabinet.xml"
# The articulated objects Meta-World 3.1.1 ships (each compiles standalone in MuJoCo).
METAWORLD = {
    "drawer": ("prismatic",),
    "faucet": ("revolute",),
    "lever": ("revolute",),
    "handle_press": ("prismatic",),
    "window": ("prismatic",),
    "window_horiz": ("prismatic",),
    "doorlockA": ("revolute",),
    "buttonbox": ("prismatic",),
    "laptop": ("revolute",),
    "dial": ("revolute",),
    "coffeemachine": ("prismatic",),
}


def importer(*args, check=True):
    p = subprocess.run(
        [sys.executable, "-m", "umpnet.objects", *map(str, args)],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    if check and p.returncode != 0:
        raise AssertionError(f"importer {args} exited {p.returncode}: {p.stderr}")
    return p


def umpnet_cli(*args, check=True):
    p = subprocess.run([UMPNET, *map(str, args)], check=False, capture_output=True, text=True, timeout=600)
    if check and p.returncode != 0:
        raise AssertionError(f"umpnet {args} exited {p.returncode}: {p.stderr}")
    return p


@pytest.fixture(scope="module")
def external(tmp_path_factory):
    out = tmp_path_factory.mktemp("external")
    report = json.loads(importer("metaworld", "--out", out, "--json").stdout)
    return out, report


def joints_of(urdf: Path) -> dict:
    root = ET.parse(urdf).getroot()
    out = {}
    for j in root.iter("joint"):
        lim = j.find("limit")
        out[j.get("name")] = {
            "type": j.get("type"),
            "axis": [float(v) for v in j.find("axis").get("xyz").split()],
            "limit": (float(lim.get("lower")), float(lim.get("upper"))) if lim is not None else None,
            "parent": j.find("parent").get("link"),
            "child": j.find("child").get("link"),
        }
    return out


def test_metaworld_objects_import_and_load_and_the_rest_are_skipped_with_a_reason(external):
    out, report = external
    imported = {o["name"]: o for o in report["imported"]}
    assert set(METAWORLD) <= set(imported), sorted(imported)
    for name, kinds in METAWORLD.items():
        o = imported[name]
        assert tuple(j["type"] for j in o["joints"]) == kinds, o
        urdf = out / name / "mobility.urdf"
        meta = json.loads((out / name / "object_meta_info.json").read_text())
        # Loads through the simulator's own loader at its scene scale, stands on
        # the floor and is about as large as the generated objects.
        art = umpnet.Articulation(str(urdf), position=[0, 0, 0], scale=meta["scale"])
        verts = all_vertices(art, urdf)
        extent = (verts.max(axis=0) - verts.min(axis=0)).max()
        assert extent == pytest.approx(0.8, rel=1e-3), name
        assert verts[:, 2].min() == pytest.approx(0.0, abs=1e-4), name
        assert abs(verts[:, 0].min() + verts[:, 0].max()) < 1e-3, name
        # Scenery (Meta-World's table and wall) is not part of the object.
        assert "tablelink" in o["dropped"]
        objs = list((out / name / "textured_objs").glob("*.obj"))
        assert objs and all(p.with_suffix(".mtl").is_file() for p in objs)
        # The windows' panes are the only translucent geoms Meta-World draws (rgba alpha 0.1).
        alphas = [float(c.get("rgba").split()[3]) for c in ET.parse(urdf).getroot().iter("color")]
        assert alphas == ([0.1, 0.1] if name.startswith("window") else []), name
    skipped = {s["file"]: s["why"] for s in report["skipped"]}
    assert "no hinge or slide joint (only free joints)" in skipped["box.xml"]
    assert "MuJoCo cannot compile it" in skipped["table.xml"]


def link_names(urdf: Path) -> list:
    return [link.get("name") for link in ET.parse(urdf).getroot().iter("link")]


def all_vertices(art, urdf: Path) -> np.ndarray:
    """Every link's vertices (some links are empty: a dial's base, a helper link)."""
    return np.concatenate([np.array(art.link_vertices(n)).reshape(-1, 3) for n in link_names(urdf)])


def test_an_mjcf_cabinet_keeps_its_frames_units_parts_and_colours(tmp_path):
    report = json.loads(importer("import-mjcf", CABINET, "--out", tmp_path, "--name", "cab", "--json").stdout)
    (o,) = report["imported"]
    assert o["dropped"] == ["table"]
    urdf = tmp_path / "cab" / "mobility.urdf"
    j = joints_of(urdf)
    assert set(j) == {"left_hinge", "right_hinge", "drawer_slide"}
    # compiler angle="degree": -120..0 degrees in the file.
    assert j["left_hinge"]["type"] == "revolute"
    assert j["left_hinge"]["limit"] == pytest.approx((-2.0944, 0.0), abs=1e-4)
    # The drawer's body is turned 180 degrees about z: its +y slide opens toward -y.
    assert j["drawer_slide"]["axis"] == pytest.approx([0, -1, 0], abs=1e-6)
    assert j["drawer_slide"]["limit"] == pytest.approx((0.0, 0.3))
    # The doors open toward the camera (-y), as the file says.
    art = umpnet.Articulation(str(urdf), position=[0, 0, 0])
    for hinge, value in [("left_hinge", -1.0), ("right_hinge", 1.0)]:
        link, _, _ = art.joint_axis(hinge)
        closed = np.array(art.link_vertices(link))[:, 1].mean()
        art.set_joints({hinge: value})
        assert np.array(art.link_vertices(link))[:, 1].mean() < closed - 0.05, hinge
    # Colours come from the geoms' rgba and materials (the handles' material).
    kd = sorted({(tmp_path / "cab" / "textured_objs" / m.name).read_text().split("Kd ")[1].strip()
                 for m in (tmp_path / "cab" / "textured_objs").glob("*.mtl")})  # fmt: skip
    assert kd == ["0.5500 0.3500 0.2000", "0.8500 0.8500 0.9000"]
    # No collision-only geom (rgba 0.2 0.2 0.9) and no floor plane were drawn.
    art.set_joints({"left_hinge": 0.0, "right_hinge": 0.0})
    verts = all_vertices(art, urdf)
    assert verts[:, 0].max() - verts[:, 0].min() < 0.81


def test_refusals_name_the_file_and_the_reason(tmp_path):
    no_joint = tmp_path / "block.xml"
    no_joint.write_text(
        '<mujoco><worldbody><body><freejoint/><geom type="box" size=".1 .1 .1"/></body></worldbody></mujoco>'
    )
    broken = tmp_path / "broken.xml"
    broken.write_text(
        '<mujoco><worldbody><body><joint type="hinge"/><geom type="nonsense"/></body></worldbody></mujoco>'
    )
    missing = tmp_path / "missing_mesh.xml"
    missing.write_text(
        '<mujoco><asset><mesh name="m" file="nowhere.stl"/></asset><worldbody><body>'
        '<joint type="slide" range="0 1"/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>'
    )
    cases = [
        (no_joint, "no hinge or slide joint (only free joints)"),
        (broken, "MuJoCo cannot compile it"),
        (missing, "nowhere.stl"),
        (tmp_path / "absent.xml", "no such file"),
    ]
    for path, needle in cases:
        p = importer("import-mjcf", path, "--out", tmp_path / "out", check=False)
        assert p.returncode == 1, (path, p.stdout, p.stderr)
        line = p.stderr.strip()
        assert line.startswith(f"error: {path}") and needle in line, line
        assert "Traceback" not in p.stderr
        assert not (tmp_path / "out" / path.stem).exists()


def test_numbers_beyond_f32_or_sense_are_refused_by_element(tmp_path):
    body = (
        '<mujoco><asset><mesh name="m" vertex="0 0 0 1 0 0 0 1 0 0 0 1" scale="{scale}"/></asset>'
        '<worldbody><body><geom type="box" size=".1 .1 .1"/><body>'
        '<joint name="j" type="hinge" axis="{axis}" range="{range}"/><geom type="mesh" mesh="m"/>'
        "</body></body></worldbody></mujoco>"
    )
    ok = {"scale": "1 1 1", "axis": "0 0 1", "range": "0 1"}
    for field, value, needle in [
        ("axis", "1e39 0 0", "joint `j` axis must be finite within f32 range"),
        ("range", "-1e30 1e30", "joint `j` range"),
        ("range", "0 1e39", "joint `j` range must be finite within f32 range"),
        ("scale", "1e-300 1 1", "mesh `m` scale must be within"),
    ]:
        path = tmp_path / f"{field}.xml"
        path.write_text(body.format(**{**ok, field: value}))
        p = importer("import-mjcf", path, "--out", tmp_path / "out", check=False)
        assert p.returncode == 1 and needle in p.stderr, (field, p.stderr)
    path = tmp_path / "fine.xml"
    path.write_text(body.format(**ok))
    importer("import-mjcf", path, "--out", tmp_path / "out")


def test_a_mujocoinclude_fragment_is_wrapped_and_an_existing_object_is_kept(tmp_path):
    frag = tmp_path / "lid.xml"
    frag.write_text(
        '<mujocoinclude><body name="box"><geom type="box" size=".2 .2 .1"/>'
        '<body name="lid" pos="0 .2 .1"><joint name="lid_hinge" type="hinge" axis="1 0 0" range="0 90"/>'
        '<geom type="box" size=".2 .2 .01" pos="0 -.2 0"/></body></body></mujocoinclude>'
    )
    importer("import-mjcf", frag, "--out", tmp_path / "out")
    # MuJoCo's unit for angles is the degree unless <compiler angle="radian">.
    limit = joints_of(tmp_path / "out" / "lid" / "mobility.urdf")["lid_hinge"]["limit"]
    assert limit == pytest.approx((0.0, np.pi / 2), abs=1e-5)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".umpnet-wrap")] == []
    before = (tmp_path / "out" / "lid" / "mobility.urdf").read_bytes()
    p = importer("import-mjcf", frag, "--out", tmp_path / "out", check=False)
    assert p.returncode == 1 and "--force" in p.stderr
    assert (tmp_path / "out" / "lid" / "mobility.urdf").read_bytes() == before


def test_angle_units_follow_the_file_unless_the_including_model_sets_them(tmp_path):
    # robosuite's objects say nothing of units: the model that includes them
    # declares <compiler angle="radian"/>, and "0 0.4" means 0.4 rad there.
    door = tmp_path / "door.xml"
    door.write_text(
        '<mujoco model="door"><worldbody><body name="frame"><geom type="box" size=".02 .02 .3"/>'
        '<body name="panel" pos=".25 0 0"><joint name="hinge" type="hinge" axis="0 0 1" range="0 0.4"/>'
        '<geom type="box" size=".22 .02 .29"/></body></body></worldbody></mujoco>'
    )
    frag = tmp_path / "lid.xml"
    frag.write_text(
        '<mujocoinclude><body name="box"><geom type="box" size=".2 .2 .1"/>'
        '<body name="lid" pos="0 .2 .1"><joint name="lid_hinge" type="hinge" axis="1 0 0" range="0 1.2"/>'
        '<geom type="box" size=".2 .2 .01" pos="0 -.2 0"/></body></body></mujocoinclude>'
    )
    for file, joint, value in ((door, "hinge", 0.4), (frag, "lid_hinge", 1.2)):
        importer("import-mjcf", file, "--out", tmp_path / "file")
        urdf = tmp_path / "file" / file.stem / "mobility.urdf"
        assert joints_of(urdf)[joint]["limit"] == pytest.approx((0.0, np.radians(value)), abs=1e-6)
        importer("import-mjcf", file, "--out", tmp_path / "rad", "--angle", "radian")
        urdf = tmp_path / "rad" / file.stem / "mobility.urdf"
        assert joints_of(urdf)[joint]["limit"] == pytest.approx((0.0, value), abs=1e-6)
        meta = json.loads((urdf.parent / "object_meta_info.json").read_text())
        assert meta["source"]["angle"] == "radian"
    p = importer("import-mjcf", door, "--out", tmp_path / "bad", "--angle", "gradian", check=False)
    assert p.returncode == 2 and "--angle" in p.stderr and "radian" in p.stderr


# A cabinet written the way LIBERO's articulated objects are (robosuite's object layout):
# plain MuJoCo refuses it four ways that robosuite never meets.
ROBOSUITE_CABINET = """<mujoco model="cabinet">
  <compiler angle="radian" meshdir="no_such_folder/" inertiafromgeom="auto" inertiagrouprange="4 4"/>
  <asset>
    <mesh name="knob" file="parts/knob.obj"/>
    <material name="wood" rgba=".6 .4 .2 1"/>
    <material name="wood" rgba=".1 .9 .1 1"/>
  </asset>
  <worldbody>
    <body>
      <body name="object">
        <geom type="box" size=".3 .2 .3" pos="0 0 .3" group="1" material="wood"/>
        <geom type="box" size=".3 .2 .3" pos="0 0 .3" group="0" rgba=".3 .3 1 .5"/>
        <body name="door" pos=".3 -.21 .3">
          <joint name="hinge" type="hinge" axis="0 0 1" range="0 1.2"/>
          <geom type="box" size=".3 .01 .3" pos="-.3 0 0" group="1" rgba=".9 .9 .9 1"/>
          <geom type="box" size=".3 .01 .3" pos="-.3 0 0" group="0" rgba=".3 .3 1 .5"/>
          <geom type="mesh" mesh="knob" pos="-.5 -.02 0" group="1" rgba=".9 .9 .9 1"/>
        </body>
      </body>
      <site name="bottom_site" pos="0 0 0" size=".01"/>
      <region name="region_1" pos="0 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_robosuite_objects_are_read_as_robosuite_includes_them(tmp_path):
    """--robosuite: only the `object` body, robosuite's compiler instead of
    the file's, asset files beside the file, the first of two same-named
    assets, and group 1 (robosuite's visual group) drawn."""
    src = tmp_path / "src"
    (src / "parts").mkdir(parents=True)
    (src / "parts" / "knob.obj").write_text(
        "v 0 0 0\nv .04 0 0\nv 0 .04 0\nv 0 0 .04\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    )
    cabinet = src / "cabinet.xml"
    cabinet.write_text(ROBOSUITE_CABINET)
    p = importer("import-mjcf", cabinet, "--out", tmp_path / "plain", check=False)
    assert p.returncode == 1 and "MuJoCo cannot compile it" in p.stderr, p.stderr
    assert "robosuite's object layout" in p.stderr and "--robosuite" in p.stderr, p.stderr
    report = json.loads(importer("import-mjcf", cabinet, "--out", tmp_path / "out", "--robosuite", "--json").stdout)
    (done,) = report["imported"]
    assert [(j["type"], j["lower"], j["upper"]) for j in done["joints"]] == [("revolute", 0.0, pytest.approx(1.2))]
    warnings = " | ".join(done["warnings"])
    assert 'inertiagrouprange="4 4"' in warnings and 'meshdir="no_such_folder/"' in warnings, warnings
    assert "angle=" not in warnings and "material `wood` is named twice: the first kept" in warnings, warnings
    dest = tmp_path / "out" / "cabinet"
    meta = json.loads((dest / "object_meta_info.json").read_text())
    assert meta["source"]["included_as"] == "robosuite" and "angle" not in meta["source"]
    # Group 1 only: the first `wood` on the body, white on the door; no translucent blue collision boxes.
    colours = sorted({m.read_text().split("Kd ")[1].strip() for m in (dest / "textured_objs").glob("*.mtl")})
    assert colours == ["0.6000 0.4000 0.2000", "0.9000 0.9000 0.9000"], colours
    assert len(list((dest / "textured_objs").glob("*.obj"))) == 3  # body, door, knob
    assert [p.name for p in src.iterdir() if p.name.startswith(".umpnet-")] == []
    p = importer("import-mjcf", cabinet, "--out", tmp_path / "x", "--robosuite", "--angle", "radian", check=False)
    assert p.returncode == 2 and "--angle" in p.stderr and "--robosuite" in p.stderr, p.stderr
    loose = src / "loose.xml"
    loose.write_text(ROBOSUITE_CABINET.replace('name="object"', 'name="cabinet"'))
    p = importer("import-mjcf", loose, "--out", tmp_path / "y", "--robosuite", check=False)
    assert p.returncode == 1 and str(loose) in p.stderr and "no body named `object`" in p.stderr, p.stderr


def test_a_folder_where_no_temporary_copy_can_be_written_is_refused_by_name(tmp_path, monkeypatch):
    """A fragment and a robosuite file are compiled from a copy beside them
    (MuJoCo resolves relative paths from the file's folder); a read-only
    folder is an ImportFailed naming the file, not a traceback."""
    from umpnet.objects import mjcf

    frag = tmp_path / "lid.xml"
    frag.write_text('<mujocoinclude><body name="box"><geom type="box" size=".2 .2 .1"/></body></mujocoinclude>')
    cabinet = tmp_path / "cabinet.xml"
    cabinet.write_text(ROBOSUITE_CABINET)

    def read_only(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(mjcf.tempfile, "mkstemp", read_only)
    for path, robosuite in ((frag, False), (cabinet, True)):
        with pytest.raises(umpnet.objects.ImportFailed) as e:
            mjcf.compile_mjcf(path, robosuite=robosuite)
        assert str(path) in str(e.value) and "cannot write a temporary file beside it" in str(e.value)
        assert "Permission denied" in str(e.value)


def test_franka_kitchen_imports_its_three_appliances_and_names_what_it_leaves_out(tmp_path):
    # The scene's layout: appliances as bodies of one file that also holds
    # the robot and scenery; each becomes its own object, by body name.
    scene = tmp_path / "gr" / "envs" / "assets" / "kitchen_franka" / "kitchen_assets" / "kitchen_env_model.xml"
    scene.parent.mkdir(parents=True)
    appliance = (
        '<body name="{name}" pos="{x} 0 1"><geom type="box" size=".3 .2 .2"/>'
        '<body name="{name}_door" pos="0 -.22 0"><joint name="{name}_joint" type="{kind}" axis="{axis}" range="{range}"/>'
        '<geom type="box" size=".28 .02 .18"/></body></body>'
    )
    scene.write_text(
        '<mujoco><compiler angle="radian"/><worldbody><geom type="plane" size="5 5 .1"/>'
        '<body name="desk" pos="0 1 0">'
        + appliance.format(name="microwave", x=-1, kind="hinge", axis="0 0 1", range="-2.094 0")
        + appliance.format(name="slidecabinet", x=0, kind="slide", axis="1 0 0", range="0 .44")
        + appliance.format(name="hingecabinet", x=1, kind="hinge", axis="0 0 1", range="0 1.57")
        + appliance.format(name="ovenroot", x=2, kind="hinge", axis="0 1 0", range="-1.57 0")
        + "</body></worldbody></mujoco>"
    )
    report = json.loads(
        importer("franka-kitchen", "--from", tmp_path / "gr", "--out", tmp_path / "out", "--json").stdout
    )
    assert [i["name"] for i in report["imported"]] == ["microwave", "slidecabinet", "hingecabinet"]
    limits = {i["name"]: [(j["type"], j["lower"], j["upper"]) for j in i["joints"]] for i in report["imported"]}
    # The scene's <compiler angle="radian"/> holds: 2.094 is radians, not degrees.
    assert limits["microwave"] == [("revolute", pytest.approx(-2.094), 0.0)]
    assert limits["slidecabinet"] == [("prismatic", 0.0, pytest.approx(0.44))]
    assert sorted((tmp_path / "out").iterdir()) == [
        tmp_path / "out" / n for n in ("hingecabinet", "microwave", "slidecabinet")
    ]
    assert "ovenroot" in {s["file"] for s in report["skipped"]}
    p = importer("franka-kitchen", "--from", tmp_path / "out", "--out", tmp_path / "none", check=False)
    assert p.returncode == 1 and "kitchen_env_model.xml" in p.stderr and str(tmp_path / "out") in p.stderr


def test_a_folder_imports_its_articulated_files_and_says_why_it_skipped_the_rest(tmp_path):
    src = tmp_path / "objects"
    src.mkdir()
    (src / "door.xml").write_text(
        '<mujoco model="door"><worldbody><body name="frame"><geom type="box" size=".02 .02 .3"/>'
        '<body name="panel" pos=".25 0 0"><joint name="hinge" type="hinge" axis="0 0 1" range="0 0.4"/>'
        '<geom type="box" size=".22 .02 .29"/></body></body></worldbody></mujoco>'
    )
    (src / "can.xml").write_text(
        '<mujoco model="can"><worldbody><body name="can"><geom type="cylinder" size=".03 .06"/></body>'
        "</worldbody></mujoco>"
    )
    p = importer("import-folder", src, "--out", tmp_path / "out", "--angle", "radian", "--yaw", "90", "--json")
    report = json.loads(p.stdout)
    assert [i["name"] for i in report["imported"]] == ["door"]
    assert report["imported"][0]["joints"][0]["upper"] == pytest.approx(0.4, abs=1e-6)
    assert [s["file"] for s in report["skipped"]] == ["can.xml"] and "hinge or slide" in report["skipped"][0]["why"]
    meta = json.loads((tmp_path / "out" / "door" / "object_meta_info.json").read_text())
    assert meta["orientation"] == pytest.approx([0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    (src / "door.xml").unlink()
    p = importer("import-folder", src, "--out", tmp_path / "out2", check=False)
    assert p.returncode == 1 and "no articulated object among its 1 MJCF files" in p.stderr
    p = importer("import-folder", tmp_path / "nowhere", "--out", tmp_path / "out3", check=False)
    assert p.returncode == 1 and "no such folder" in p.stderr


def _without_wall_time(path: Path) -> dict:
    r = json.loads(path.read_text())
    r["summary"].pop("wall_seconds")
    return r


def test_eval_objects_scores_each_object_as_a_row_and_shards_merge_byte_for_byte(external, tmp_path):
    out, _ = external
    common = ["eval", "--task", "goal", "--objects", out, "--episodes-per-category", "3", "--policies", "random"]
    whole = umpnet_cli(*common, "--out", tmp_path / "whole")
    table = (tmp_path / "whole" / "table.txt").read_text()
    assert "objects" in table and "train categories" not in table
    for name in METAWORLD:
        assert name in table
    summary = _without_wall_time(tmp_path / "whole" / "results.json")["summary"]
    assert summary["categories"] == []
    rows = {o["name"] for o in summary["objects"]}
    assert set(METAWORLD) <= rows
    assert all(o["sha256"].startswith("sha256:") for o in summary["objects"])
    oracle = {c["object"]: c["mean"] for c in summary["cells"]
              if c["policy"] == "oracle" and c["metric"] == "success_rate"}  # fmt: skip
    assert set(oracle) == rows
    # The oracle is the ceiling; any object where it falls short is named, not dropped.
    short = sorted(name for name, mean in oracle.items() if mean < 0.95)
    for name in short:
        assert f"{name} {oracle[name]:.2f}" in whole.stdout
    assert sum(oracle[n] for n in METAWORLD) / len(METAWORLD) > 0.8
    csv = (tmp_path / "whole" / "results.csv").read_text().splitlines()
    assert any(line.startswith("oracle,average,objects,success_rate") for line in csv)
    # Shards of the same run merge into it, byte for byte but the wall time.
    for k in (1, 2):
        umpnet_cli(*common, "--shard", f"{k}/2", "--out", tmp_path / f"s{k}")
    umpnet_cli("eval", "merge", tmp_path / "s1", tmp_path / "s2", "--out", tmp_path / "merged")
    assert _without_wall_time(tmp_path / "merged" / "results.json") == _without_wall_time(
        tmp_path / "whole" / "results.json"
    )
    assert (tmp_path / "merged" / "table.txt").read_bytes() == table.encode()


def test_eval_objects_with_categories_and_bad_folders(external, tmp_path):
    out, _ = external
    p = umpnet_cli("--json", "eval", "--task", "exploration", "--objects", out, "--categories", "Door",
                   "--episodes-per-category", "1", "--policies", "random")  # fmt: skip
    summary = json.loads(p.stdout)
    assert summary["categories"] == ["Door"] and len(summary["objects"]) >= len(METAWORLD)
    empty = tmp_path / "empty"
    empty.mkdir()
    for folder in (empty, tmp_path / "absent"):
        p = umpnet_cli("eval", "--objects", folder, check=False)
        assert p.returncode == 2, p.stderr
        assert str(folder) in p.stderr and "Traceback" not in p.stderr


def test_one_body_of_a_scene_file_is_imported_alone(tmp_path):
    report = json.loads(importer("import-mjcf", CABINET, "--body", "left_door", "--out", tmp_path, "--json").stdout)
    (o,) = report["imported"]
    assert o["name"] == "left_door" and [j["name"] for j in o["joints"]] == ["left_hinge"]
    urdf = tmp_path / "left_door" / "mobility.urdf"
    art = umpnet.Articulation(str(urdf), position=[0, 0, 0])
    # Only the door and its handle: the carcass around it is not part of the object.
    assert np.ptp(all_vertices(art, urdf)[:, 2]) == pytest.approx(0.66, abs=1e-3)
    p = importer("import-mjcf", CABINET, "--body", "hinge", "--out", tmp_path, check=False)
    assert p.returncode == 1
    assert "no body named `hinge`" in p.stderr and "carcass, drawer, left_door, right_door" in p.stderr
    p = importer("import-mjcf", CABINET, "--body", "table", "--out", tmp_path, check=False)
    assert p.returncode == 1 and "no hinge or slide joint in body `table`" in p.stderr


GLASS_BOX = """<mujoco><worldbody><body name="case">
  <geom type="box" size=".3 .2 .3" pos="0 0 .3" rgba=".8 .2 .1 1"/>
  <body name="door" pos=".3 -.22 .3">
    <joint name="hinge" type="hinge" axis="0 0 1" range="-1.5 0"/>
    <geom type="box" size=".3 .01 .28" pos="-.3 0 0" rgba=".6 .8 .9 {alpha}"/>
  </body>
  <body name="flap" pos="0 .2 .62">
    <joint name="flap" type="hinge" axis="1 0 0" range="0 1"/>
    <geom type="box" size=".1 .1 .01" pos="0 .1 0" rgba=".2 .9 .2 0"/>
  </body>
</body></worldbody></mujoco>"""


def test_a_translucent_geom_is_drawn_as_glass_and_a_hidden_one_drawn_for_want_of_others_is_opaque(tmp_path):
    frames = {}
    for alpha in ["0.3", "1"]:
        xml = tmp_path / f"glass_{alpha}.xml"
        xml.write_text(GLASS_BOX.format(alpha=alpha))
        importer("import-mjcf", xml, "--out", tmp_path, "--name", f"case_{alpha}")
        urdf = tmp_path / f"case_{alpha}" / "mobility.urdf"
        # The door's alpha becomes its URDF material's; the flap (alpha 0, the only
        # geom of its link, so drawn from it) and the case stay opaque.
        colors = [c.get("rgba").split() for c in ET.parse(urdf).getroot().iter("color")]
        assert colors == ([["0.6000", "0.8000", "0.9000", "0.3000"]] if alpha != "1" else []), colors
        out = tmp_path / f"render_{alpha}"
        umpnet_cli("--json", "render", "--object", urdf, "--renderer", "cpu", "--resolution", "60x80",
                   "--seed", "1", "--out", out)  # fmt: skip
        rgb = np.asarray(Image.open(out / "color.png").convert("RGB"), dtype=np.int32)
        seg = np.asarray(Image.open(out / "segmentation.png").convert("RGB"), dtype=np.int32)
        frames[alpha] = (rgb, seg, np.load(out / "depth.npy"))
    (glass, seg_g, depth_g), (solid, seg_s, depth_s) = frames["0.3"], frames["1"]
    # Same geometry, so the same depth and segments; only the colour shows the case through the door.
    assert np.array_equal(depth_g, depth_s) and np.array_equal(seg_g, seg_s)
    changed = np.any(glass != solid, axis=2)
    assert 20 < changed.sum() < changed.size / 2, changed.sum()
    # Through the door the red case shows: more red than the opaque door has.
    assert (glass[changed][:, 0] > solid[changed][:, 0]).mean() > 0.9
