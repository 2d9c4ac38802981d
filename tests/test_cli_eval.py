"""End-to-end tests of `umpnet eval`: the benchmark's tables and their
determinism, shards and their merge, the shipped model's floor, the
baselines, and PartNet folders."""

import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from umpnet_cli import ROOT, SHIPPED, run


def test_eval_is_identical_for_one_and_two_threads(tmp_path):
    results = []
    for threads in ["1", "2"]:
        d = tmp_path / threads
        run(
            "eval",
            "--task",
            "goal",
            "--categories",
            "Door,Laptop",
            "--episodes-per-category",
            "4",
            "--threads",
            threads,
            "--out",
            str(d),
        )
        results.append((d / "results.csv").read_text())
        assert (d / "curve.png").stat().st_size > 1000
        # The curve says what it averages, on whole steps, with its interval.
        svg = (d / "curve.svg").read_text()
        about = "mean and 95% interval; train categories (held-out instances) and test categories ("
        assert about in svg and "8 episodes each)" in svg, svg[:2000]
        ticks = re.findall(r">\s*([0-9.]+)\s*</text>", svg)
        assert "2" in ticks and "2.0" not in ticks, ticks
        assert "<polygon" in svg  # the bands (none drawn where every episode agrees)
        assert "oracle" in (d / "table.txt").read_text()
    assert results[0] == results[1]
    # Success rates carry Wilson intervals: 4 of 4 is not "1.00 +- 0.00".
    rows = [r.split(",") for r in results[0].splitlines()]
    assert rows[0] == ["policy", "category", "split", "metric", "mean", "ci95", "ci_low", "ci_high", "n"]
    oracle = [r for r in rows if r[0] == "oracle" and r[3] == "success_rate" and r[1] != "average"]
    assert oracle and all(float(r[4]) == 1.0 and 0.4 < float(r[6]) < 0.6 for r in oracle), oracle
    assert any(r[1] == "average" for r in rows)
    assert "| **average** |" in (tmp_path / "2" / "results.md").read_text()
    assert "\\begin{tabular}" in (tmp_path / "2" / "results.tex").read_text()


def test_each_policy_sees_its_own_resolution_so_listing_others_changes_nothing(tmp_path, fixture_package):
    """Scripted policies see --resolution and a learned one its package's input;
    random's episodes are the same whether or not a learned policy is listed."""
    fixture = fixture_package
    common = ["eval", "--task", "goal", "--categories", "Door,Microwave", "--episodes-per-category", "3", "--seed", "7"]
    run(*common, "--policies", "oracle,random", "--out", str(tmp_path / "a"))
    p = run(*common, "--policies", f"umpnet={fixture},oracle,random", "--out", str(tmp_path / "b"))
    meta = json.loads(Path(fixture, "model.json").read_text())["input"]
    assert "images: oracle, random at 120x160" in p.stdout and f"umpnet at {meta['height']}x{meta['width']}" in p.stdout
    b = json.loads((tmp_path / "b" / "results.json").read_text())
    assert b["summary"]["resolutions"] == {
        "oracle": [120, 160],
        "random": [120, 160],
        "umpnet": [meta["height"], meta["width"]],
    }

    def episodes(d, policy):
        lines = (tmp_path / d / "episodes.jsonl").read_text().splitlines()
        return [line for line in lines if json.loads(line)["policy"] == policy]

    for policy in ("random", "oracle"):
        assert episodes("a", policy) == episodes("b", policy) and len(episodes("a", policy)) == 6, policy


def _without_wall_time(path: Path) -> bytes:
    return re.sub(rb'"wall_seconds":[-0-9.eE+]+', b"", path.read_bytes())


def test_sharded_eval_merges_to_the_unsharded_run_byte_for_byte(tmp_path):
    # A learned policy in the mix: its candidates' floats must survive the JSON round trip exactly.
    common = ["eval", "--task", "goal", "--categories", "Door,Laptop,Box", "--episodes-per-category", "3"]
    common += ["--policies", "random,umpnet", "--renderer", "cpu", "--threads", "2"]
    run(*common, "--out", str(tmp_path / "whole"))
    shards = []
    for k in (3, 1, 2):  # any order
        d = tmp_path / f"shard{k}"
        out = run(*common, "--shard", f"{k}/3", "--out", str(d)).stdout
        assert f"shard {k}/3" in out
        # The shard's episodes and summary, no partial tables.
        assert sorted(p.name for p in d.iterdir()) == ["episodes.jsonl", "results.json", "run.json"]
        summary = json.loads((d / "results.json").read_text())["summary"]
        assert summary["shard"] == f"{k}/3" and summary["models"]["umpnet"].startswith("sha256:")
        shards.append(str(d))
    run("eval", "merge", *shards, "--out", str(tmp_path / "merged"))
    whole, merged = tmp_path / "whole", tmp_path / "merged"
    assert _without_wall_time(merged / "results.json") == _without_wall_time(whole / "results.json")
    for name in ("results.csv", "results.md", "results.tex", "table.txt", "curve.png", "curve.svg"):
        assert (merged / name).read_bytes() == (whole / name).read_bytes(), name
    assert (merged / "episodes.jsonl").read_bytes() == (whole / "episodes.jsonl").read_bytes()
    n = len((whole / "episodes.jsonl").read_text().splitlines())
    assert n == json.loads((whole / "results.json").read_text())["summary"]["episodes"] == 3 * 3 * 3

    # Incomplete, repeated or foreign shards are refused with the reason.
    p = run("eval", "merge", shards[0], shards[1], check=False)  # shards 3 and 1
    assert p.returncode == 2 and "missing shards: 2/3" in p.stderr
    p = run("eval", "merge", shards[0], shards[0], shards[1], check=False)
    assert p.returncode == 2 and "given twice" in p.stderr
    p = run("eval", "merge", str(whole), check=False)
    assert p.returncode == 2 and "not a shard" in p.stderr
    other = tmp_path / "other"
    run(*common[:7], "--policies", "random", "--renderer", "cpu", "--shard", "1/3", "--out", str(other))
    p = run("eval", "merge", str(other), shards[1], shards[2], check=False)
    assert p.returncode == 2 and "not a shard of the same evaluation" in p.stderr and "policies" in p.stderr


FLOORS = {"goal": "success_rate", "exploration": "novel_state_ratio"}


# model.json's evaluation names for the metrics of FLOORS.
REPORTED = {"success_rate": "goal_success", "novel_state_ratio": "novel_state_ratio"}


def _pooled(cells, policy, metric):
    """Mean over the categories (equal episode counts) and its 95% half-width
    from the per-category intervals."""
    mine = [c for c in cells if c["policy"] == policy and c["metric"] == metric]
    assert mine, (policy, metric)
    return sum(c["mean"] for c in mine) / len(mine), math.sqrt(sum(c["ci95"] ** 2 for c in mine)) / len(mine)


@pytest.mark.parametrize("task", list(FLOORS))
def test_the_shipped_model_holds_its_reported_figure_and_weaker_models_do_not(task, fixture_package):
    """On fixed test scenes (10 per category), the shipped model must reach the
    figure model.json reports minus the 95% interval of this sample. A stale or
    mismatched export, or a model at the baselines' level, falls under it: the
    untrained fixture package and the best one-budget baseline are required to."""
    shipped = SHIPPED
    metric = FLOORS[task]
    reported = json.loads((shipped / "model.json").read_text())["evaluation"][REPORTED[metric]]["test"]
    weaker = {"untrained": fixture_package, "aot-only": str(ROOT / "models" / "baselines" / "aot-only")}
    policies = ",".join([f"shipped={shipped}"] + [f"{k}={v}" for k, v in weaker.items()])
    res = json.loads(
        run("--json", "eval", "--task", task, "--split", "test", "--episodes-per-category", "10",
            "--policies", policies).stdout
    )  # fmt: skip
    mean, half = _pooled(res["cells"], "shipped", metric)
    floor = reported - half
    # This sample's half-width is about 0.07 (10 scenes a category).
    assert mean >= floor, (task, metric, mean, floor)
    for name in weaker:
        theirs, _ = _pooled(res["cells"], name, metric)
        assert theirs < floor, (name, theirs, floor)


def test_the_binary_and_the_wheel_default_to_one_package(tmp_path):
    """Without --model, `umpnet` runs the package the wheel ships as
    `Policy.default()`, and says which one by its hash."""
    assert (SHIPPED / "model.json").is_file() and SHIPPED.parent == ROOT / "models", SHIPPED
    hashes = {}
    for name, model in {
        "default": [],
        "wheel": ["--model", str(SHIPPED)],
        "other": ["--model", str(ROOT / "models" / "umpnet-small")],
    }.items():
        out = tmp_path / name
        run("eval", "--task", "goal", "--categories", "Door", "--episodes-per-category", "1", "--policies", "umpnet",
            *model, "--out", str(out))  # fmt: skip
        hashes[name] = json.loads((out / "run.json").read_text())["models"]["umpnet"]
    assert hashes["default"] == hashes["wheel"] != hashes["other"], hashes


BASELINES = ["umpnet-300", "single-step", "aot-only", "signed-dist", "where2act", "where2act-normal90", "inverse"]


def test_shipped_baselines_load_and_run_the_benchmark(tmp_path):
    """`make eval-baselines` in small: every package loads and runs both tasks,
    and scripts/baselines_table.py turns the results into the README's table."""
    specs = {b: f"{b}={ROOT / 'models' / 'baselines' / b}" for b in BASELINES}
    out = {task: tmp_path / f"baselines-{task}-test" for task in ("goal", "exploration")}
    for task, folder in out.items():
        policies = ",".join(["umpnet"] + [s for b, s in specs.items() if task == "goal" or b != "inverse"])
        run("eval", "--task", task, "--categories", "Door,Box", "--episodes-per-category", "2",
            "--policies", policies, "--out", str(folder))  # fmt: skip
    rows = [line.split(",") for line in (out["goal"] / "results.csv").read_text().splitlines()[1:]]
    for b in BASELINES:
        counts = [int(r[-1]) for r in rows if r[0] == b and r[1] != "average"]
        assert counts and all(n == 2 for n in counts), f"{b}: episodes failed or missing"
    for b in BASELINES:
        meta = json.loads((ROOT / "models" / "baselines" / b / "model.json").read_text())
        assert meta["provenance"]["epochs"] == 300 and meta["provenance"]["seed"] == 0
    table = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "baselines_table.py"), "--out", str(tmp_path), "--json"],
        check=True, capture_output=True, text=True,
    )  # fmt: skip
    t = json.loads(table.stdout)
    averages = {(r[0], r[3]): float(r[4]) for r in rows if r[1] == "average"}  # one split: the test categories
    for b in ["umpnet", *BASELINES]:
        mean, half = t["table"][b]["goal success"]
        assert abs(mean - averages[(b, "success_rate")]) < 1e-6 and half >= 0
    assert "novel-state ratio" not in t["table"]["inverse"]
    pairs = {(c["umpnet"], c["baseline"], c["metric"]) for c in t["comparisons"]}
    assert ("umpnet-300", "where2act", "novel-state ratio") in pairs
    assert ("umpnet", "inverse", "goal success") in pairs
    assert ("umpnet", "inverse", "novel-state ratio") not in pairs
    for c in t["comparisons"]:
        assert c["beats"] == (c["advantage"] - c["ci95"] > 0)
    # The Inverse model has no exploration behaviour: a clear usage error, not a failed episode.
    p = run("eval", "--task", "exploration", "--categories", "Door", "--episodes-per-category", "1",
            "--policies", f"inverse={ROOT / 'models' / 'baselines' / 'inverse'}", check=False)  # fmt: skip
    assert p.returncode == 2 and "serves only the goal task" in p.stderr


def test_paper_rows_set_each_category_beside_the_papers_figure(tmp_path):
    ev = ["eval", "--categories", "Door,Laptop", "--episodes-per-category", "2"]
    run(*ev, "--policies", "umpnet,random", "--out", str(tmp_path / "plain"))
    run(*ev, "--policies", "umpnet", "--direction-filter", "prev90", "--out", str(tmp_path / "hp"))
    script = [sys.executable, str(ROOT / "scripts" / "paper_rows.py"), str(tmp_path / "plain"), str(tmp_path / "hp")]
    rows = json.loads(subprocess.run([*script, "--json"], check=True, capture_output=True, text=True).stdout)
    got = {(r["policy"], r["category"], r["metric"]): r for r in rows}
    # The paper's Table I: Door is its last test column, Laptop its third training one.
    assert got[("umpnet", "Door", "novel_state_ratio")]["paper"] == 0.68
    assert got[("umpnet", "Laptop", "single_action_effect")]["paper"] == 1.37
    assert got[("umpnet+prev90", "Door", "novel_state_ratio")]["paper_method"] == "UMPNet+HP"
    assert got[("umpnet+prev90", "Door", "novel_state_ratio")]["paper"] == 0.70
    assert got[("random", "Door", "novel_state_ratio")]["paper"] is None
    assert got[("umpnet", "Door", "novel_state_ratio")]["split"] == "test"
    assert got[("umpnet", "Laptop", "novel_state_ratio")]["split"] == "train"
    md = subprocess.run(script, check=True, capture_output=True, text=True).stdout
    head = "| category | umpnet | paper: UMPNet | random | oracle | umpnet+prev90 | paper: UMPNet+HP |"
    assert head in md, md
    missing = subprocess.run([*script[:2], str(tmp_path / "none")], check=False, capture_output=True, text=True)
    assert missing.returncode == 1 and "results.json not found" in missing.stderr


def make_partnet_folder(root, tmp_path):
    """A small folder in both PartNet layouts, built from generated objects:
    UMPNet's mobility_dataset (<Category>/<id>/) for Microwave and
    PartNet-Mobility's own (<id>/ with meta.json) for Door, with the released
    split's file format."""
    gen = tmp_path / "gen"
    run("objects", "generate", "--out", str(gen), "--per-category", "4", "--categories", "Microwave,Door")
    for k, id_ in enumerate(["101", "102", "103"]):
        shutil.copytree(gen / "Microwave" / str(k), root / "Microwave" / id_)
    for k, id_ in enumerate(["8867", "8868"]):
        shutil.copytree(gen / "Door" / str(k), root / id_)
        (root / id_ / "meta.json").write_text(json.dumps({"model_cat": "Door", "anno_id": id_}))
    split = {
        "train": {"Microwave": {"train": ["101"], "test": ["102", 103]}},
        "test": {"Door": {"test": ["8867", "8868"]}},
    }
    (root / "split-full.json").write_text(json.dumps(split))


def test_partnet_folder_with_the_released_split_scores_the_held_out_instances(tmp_path):
    """`eval --partnet DIR` scores each category on the folder's instances
    the released split names (a training category's held-out ones, a test
    category's all), records them in results.json, and names what is wrong
    with a folder."""
    root = tmp_path / "mobility_dataset"
    make_partnet_folder(root, tmp_path)
    out = tmp_path / "eval"
    run(
        "eval",
        "--task",
        "exploration",
        "--partnet",
        str(root),
        "--episodes-per-category",
        "6",
        "--policies",
        "random",
        "--out",
        str(out),
    )
    summary = json.loads((out / "results.json").read_text())["summary"]
    assert summary["categories"] == ["Microwave", "Door"], summary["categories"]
    names = [i["name"] for i in summary["partnet"]["instances"]]
    assert names == ["Microwave/102", "Microwave/103", "Door/8867", "Door/8868"], names
    assert "split-full.json sha256:" in summary["partnet"]["split_file"]
    used = {}
    for line in (out / "episodes.jsonl").read_text().splitlines():
        o = json.loads(line)
        used.setdefault(o["category"], set()).add(Path(o["episode"]["scene"]["object"]["path"]).parent.name)
    # The trained-on instance 101 is never scored; each listed one is.
    assert used == {"Microwave": {"102", "103"}, "Door": {"8867", "8868"}}, used
    # Without the split file: every instance found, in both layouts.
    (root / "split-full.json").rename(tmp_path / "split.json")
    found = json.loads(
        run(
            "--json",
            "eval",
            "--task",
            "goal",
            "--partnet",
            str(root),
            "--episodes-per-category",
            "3",
            "--policies",
            "random",
        ).stdout
    )
    assert "split_file" not in found["partnet"] and len(found["partnet"]["instances"]) == 5
    # What is wrong is named.
    p = run("eval", "--partnet", str(root), "--categories", "Oven", "--policies", "random", check=False)
    assert p.returncode == 2 and "no instances of Oven" in p.stderr, p.stderr
    (root / "Microwave" / "103" / "object_meta_info.json").unlink()
    p = run("eval", "--partnet", str(root), "--split-file", str(tmp_path / "split.json"), check=False)
    assert p.returncode == 2 and "Microwave 103" in p.stderr and "object_meta_info.json" in p.stderr, p.stderr
    (tmp_path / "typo.json").write_text(json.dumps({"train": {"Microwav": {"test": ["102"]}}}))
    p = run("eval", "--partnet", str(root), "--split-file", str(tmp_path / "typo.json"), check=False)
    assert p.returncode == 2 and "Microwav" in p.stderr and "did you mean Microwave" in p.stderr, p.stderr
