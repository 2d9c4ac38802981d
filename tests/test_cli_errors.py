"""End-to-end tests of how the `umpnet` binary fails: usage errors in one
line (one JSON line under --json), files and outputs it cannot honour named,
output folders never overwritten silently, and no panic."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from umpnet_cli import ROOT, UMPNET, run

BAD_USAGE = [
    (["explore"], 2, "--category"),
    (["explore", "--category", "Spaceship"], 2, "unknown category"),
    (["explore", "--category", "Spaceship"], 2, "or a test category (Box, Phone,"),
    (["explore", "--category", "drawer"], 2, "did you mean StorageFurniture"),
    (["eval", "--split", "nope"], 2, "--split nope"),
    (["render", "--category", "Door", "--resolution", "12", "--out", "/tmp/x"], 2, "HEIGHTxWIDTH"),
    (["explore", "--object", "/nonexistent/mobility.urdf"], 2, "no such file"),
    (["eval", "--threads", "5000"], 2, "5000 is not in 1..=1024"),
]


@pytest.mark.parametrize("args, code, needle", BAD_USAGE)
def test_bad_usage_exits_2_with_one_line(args, code, needle):
    p = run(*args, check=False)
    assert p.returncode == code, p.stderr
    assert needle in p.stderr


@pytest.mark.parametrize("args, code, needle", [*BAD_USAGE, (["explore", "--object", "BROKEN"], 1, "mobility.urdf")])
def test_under_json_an_error_is_one_json_line_with_its_exit_code(tmp_path, args, code, needle):
    broken = tmp_path / "mobility.urdf"
    broken.write_text("<robot name='x'><link name='a'/><joint name='j'")
    args = [str(broken) if a == "BROKEN" else a for a in args]
    p = run(*args, "--json", check=False)
    assert p.returncode == code and p.stdout == "", (p.stdout, p.stderr)
    lines = p.stderr.splitlines()
    assert len(lines) == 1, p.stderr
    err = json.loads(lines[0])
    assert err["exit_code"] == code and needle in err["error"], err
    assert err["causes"] and all(c in err["error"] for c in err["causes"]), err


def test_a_portrait_resolution_is_rendered_as_asked_with_a_warning(tmp_path):
    p = run("render", "--category", "Door", "--resolution", "64x48", "--out", str(tmp_path))
    assert "64 rows by 48 columns" in p.stderr and "did you mean 48x64" in p.stderr, p.stderr
    camera = json.loads((tmp_path / "camera.json").read_text())
    assert (camera["height"], camera["width"]) == (64, 48)


def test_broken_object_file_exits_1_naming_the_file(tmp_path):
    bad = tmp_path / "mobility.urdf"
    bad.write_text(
        '<robot name="x"><link name="a"/><joint name="j" type="revolute"><parent link="a"/>'
        '<child link="missing"/><axis xyz="0 0 1"/><limit lower="0" upper="1"/></joint></robot>'
    )
    p = run("explore", "--object", str(bad), check=False)
    assert p.returncode == 1
    assert str(bad) in p.stderr and "child link `missing` does not exist" in p.stderr
    assert p.stderr.count("\n") == 1


def test_output_folders_are_claimed_never_overwritten_silently(tmp_path):
    gen = ["objects", "generate", "--per-category", "1", "--categories", "Door", "--out"]
    run(*gen, str(tmp_path / "objs"))
    before = (tmp_path / "objs" / "split.json").read_bytes()
    p = run(*gen, str(tmp_path / "objs"), "--seed", "1", check=False)
    assert p.returncode == 2 and "already holds" in p.stderr and "--force" in p.stderr, p.stderr
    assert (tmp_path / "objs" / "split.json").read_bytes() == before
    run(*gen, str(tmp_path / "objs"), "--seed", "1", "--force")
    assert json.loads((tmp_path / "objs" / "split.json").read_text())["dataset_seed"] == 1
    ev = ["eval", "--categories", "Door", "--episodes-per-category", "1", "--policies", "random", "--out"]
    run(*ev, str(tmp_path / "ev"))
    first = (tmp_path / "ev" / "results.json").read_bytes()
    p = run(*ev, str(tmp_path / "ev"), "--seed", "9", check=False)
    assert p.returncode == 2 and "already holds" in p.stderr and "results.json" in p.stderr, p.stderr
    assert (tmp_path / "ev" / "results.json").read_bytes() == first
    run(*ev, str(tmp_path / "ev"), "--seed", "9", "--force")
    assert (tmp_path / "ev" / "results.json").read_bytes() != first
    assert not (tmp_path / "ev" / ".umpnet.lock").exists()
    # A folder another run holds is refused, even with --force, and left alone.
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / ".umpnet.lock").write_text("")
    p = run(*ev, str(tmp_path / "busy"), "--force", check=False)
    assert p.returncode == 2 and "another umpnet run is writing here" in p.stderr, p.stderr
    assert (tmp_path / "busy" / ".umpnet.lock").exists() and not (tmp_path / "busy" / "results.json").exists()
    # A folder that cannot be made says so and names it.
    (tmp_path / "file").write_text("x")
    p = run(*gen, str(tmp_path / "file" / "objs"), check=False)
    assert p.returncode == 1 and "file/objs: cannot create" in p.stderr, p.stderr


def test_unix_manners_and_clear_lookups(tmp_path):
    # A closed pipe ends the listing quietly, as Unix tools do.
    p = subprocess.run(
        f"{UMPNET} objects list | head -1", shell=True, capture_output=True, text=True, timeout=120, check=False
    )
    assert p.returncode == 0 and p.stdout.strip() and "panicked" not in p.stderr, p.stderr
    # One policy listed twice would merge two runs into one cell.
    p = run("eval", "--categories", "Door", "--episodes-per-category", "1", "--policies", "oracle,oracle", check=False)
    assert p.returncode == 2 and "listed twice" in p.stderr
    # Outside the repository, with no model installed: say where it looked.
    lonely = tmp_path / "bin" / "umpnet"
    lonely.parent.mkdir()
    lonely.write_bytes(Path(UMPNET).read_bytes())
    lonely.chmod(0o755)
    env = {k: v for k, v in os.environ.items() if k != "UMPNET_MODEL"} | {"XDG_DATA_HOME": str(tmp_path / "data")}
    args = [str(lonely), "explore", "--category", "Door", "--policy", "umpnet"]
    p = subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120, check=False)
    assert p.returncode == 2 and "UMPNET_MODEL" in p.stderr and str(tmp_path / "data") in p.stderr, p.stderr
    # ...and finds one the way an installed tool does; ONNX Runtime likewise
    # (ORT_DYLIB_PATH), and its message says so, once.
    env["UMPNET_MODEL"] = str(ROOT / "models" / "umpnet-small")
    p = subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300, check=False)
    if p.returncode != 0:
        assert "ORT_DYLIB_PATH" in p.stderr and p.stderr.count("ONNX Runtime:") == 1, p.stderr
        import onnxruntime

        libs = sorted((Path(onnxruntime.__file__).parent / "capi").glob("libonnxruntime.so*"))
        env["ORT_DYLIB_PATH"] = str(libs[0])
        p = subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300, check=False)
    assert p.returncode == 0, p.stderr


def test_outputs_and_counts_that_cannot_be_honoured_are_errors_not_panics():
    # A full standard output is an error naming it, not a panic.
    for args in (["objects", "list"], ["--json", "explore", "--category", "Door", "--steps", "2"]):
        with open("/dev/full", "w") as full:
            p = subprocess.run([UMPNET, *args], stdout=full, stderr=subprocess.PIPE, text=True, check=False)
        assert p.returncode == 1 and "writing to standard output" in p.stderr, p.stderr
        assert "panicked" not in p.stderr
    # Counts beyond what can run, or that leave nothing to measure, are refused by flag.
    p = run("explore", "--category", "Door", "--steps", "18446744073709551615", check=False)
    assert p.returncode == 2 and "--steps" in p.stderr and "1 to 10000" in p.stderr, p.stderr
    p = run("bench", "--frames", "0", "--actions", "0", check=False)
    assert p.returncode == 2 and "--frames" in p.stderr and "from 1" in p.stderr, p.stderr
    # A category listed twice would count its row's episodes twice; a nameless package has no row.
    p = run("eval", "--categories", "Microwave,Microwave", "--episodes-per-category", "1", check=False)
    assert p.returncode == 2 and "Microwave is listed twice" in p.stderr, p.stderr
    p = run("eval", "--categories", "Door", "--policies", "=models/umpnet-small", check=False)
    assert p.returncode == 2 and "NAME=MODEL_DIR with both parts" in p.stderr, p.stderr


def test_inputs_that_are_not_regular_files_or_lie_about_their_size_are_refused_unread(tmp_path):
    frame = tmp_path / "frame"
    run("render", "--category", "Microwave", "--seed", "1", "--out", str(frame))
    good = {"--rgb": frame / "color.png", "--depth": frame / "depth.npy", "--camera": frame / "camera.json"}
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)

    def infer(**swap):
        paths = good | {f"--{k}": v for k, v in swap.items()}
        return run("infer", *[str(x) for kv in paths.items() for x in kv], check=False)

    # A FIFO or a device would block or never end: refused by name before a read.
    for flag in ("rgb", "depth", "camera"):
        p = infer(**{flag: fifo})
        assert p.returncode == 2 and "fifo" in p.stderr and "not a regular file" in p.stderr, (flag, p.stderr)
    p = infer(camera=Path("/dev/zero"))
    assert p.returncode == 2 and "/dev/zero" in p.stderr and "not a regular file" in p.stderr, p.stderr
    # A .npy header that claims more than the file holds is refused before allocating it.
    data = good["--depth"].read_bytes()
    h, w = np.load(good["--depth"]).shape
    lie = tmp_path / "lie.npy"
    lie.write_bytes(data.replace(f"({h}, {w})".encode(), f"({h * 1000}, {w})".encode(), 1))
    p = infer(depth=lie)
    assert p.returncode == 1 and "lie.npy" in p.stderr and "but the file holds" in p.stderr, p.stderr
    # A material library that is a FIFO is skipped (colours are decoration), not waited on.
    run("objects", "generate", "--per-category", "1", "--categories", "Door", "--out", str(tmp_path / "objs"))
    urdf = next((tmp_path / "objs").rglob("mobility.urdf"))
    obj = next(urdf.parent.rglob("*.obj"))
    obj.write_text("mtllib trap.mtl\nusemtl m\n" + obj.read_text())
    os.mkfifo(obj.with_name("trap.mtl"))
    out = json.loads(run("--json", "explore", "--object", str(urdf), "--steps", "2").stdout)
    assert len(out["steps"]) == 2


def test_network_outputs_that_are_not_numbers_or_out_of_range_are_errors_naming_the_network(
    tmp_path, fixture_package, poisoned_package
):
    fixture = fixture_package
    cases = [
        ("position.onnx", "affordance", float("nan"), "explore"),
        ("direction_decoder.onnx", "distance", float("nan"), "goal"),
        ("direction_decoder.onnx", "aot_probs", float("inf"), "explore"),
        ("direction_decoder.onnx", "distance", -100.0, "goal"),
    ]
    for k, (file, output, value, task) in enumerate(cases):
        pkg = poisoned_package(fixture, tmp_path / f"p{k}", file, output, value)
        p = run(task, "--category", "Door", "--policy", f"bad={pkg}", check=False)
        assert p.returncode == 1 and file in p.stderr and f"output `{output}`" in p.stderr, (file, output, p.stderr)
        assert '"success": true' not in p.stdout
