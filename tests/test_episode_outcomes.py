"""scripts/episode_outcomes.py on hand-made episodes whose breakdown is known."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "episode_outcomes.py"


def move(moved: bool, aot: int = 0, limit: bool = False) -> dict:
    return {"record": {"labels": {"moved": moved, "aot": aot, "reached_limit": limit}}}


def episode(task: str, valid: bool, steps: list[dict], **metrics) -> dict:
    return {"scene": {"task": task}, "valid_position": valid, "steps": steps, "metrics": metrics}


def write_run(folder: Path, records: list[dict]) -> Path:
    folder.mkdir()
    (folder / "results.json").write_text(json.dumps({"episodes_file": "episodes.jsonl"}))
    (folder / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))
    return folder


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], check=False, capture_output=True, text=True, timeout=60)


def test_each_episode_and_move_is_counted_where_it_belongs(tmp_path):
    box = [
        episode("exploration", False, [], novel_state_ratio=0.0),
        episode("exploration", True, [move(False), move(False)], novel_state_ratio=0.5),
        episode(
            "exploration",
            True,
            [move(False), move(True, 1), move(True, 0, limit=True), move(True, -1)],
            novel_state_ratio=0.75,
        ),
        episode("exploration", True, [move(True, 1)], novel_state_ratio=1.0),
    ]
    records = [{"category": "Box", "index": i, "policy": "umpnet", "episode": e} for i, e in enumerate(box)]
    # Another policy's episode and a failed one are not counted.
    records.append({"category": "Box", "index": 0, "policy": "oracle", "episode": box[3]})
    records.append({"category": "Box", "index": 9, "policy": "umpnet", "episode": None, "error": "boom"})
    # Objects are rows by name; toward a goal the score is success.
    goal = episode("goal", True, [move(True, -1), move(True, -1)], success=True, normalized_distance=0.0)
    records.append({"object": "drawer", "index": 0, "policy": "umpnet", "episode": goal})
    p = run(str(write_run(tmp_path / "run", records)), "--json")
    assert p.returncode == 0, p.stderr
    rows = json.loads(p.stdout)
    assert set(rows) == {"Box", "drawer"}
    b = rows["Box"]
    assert b["episodes"] == 4 and b["grasps"] == 0.75
    assert (b["dead"], b["late"], b["moved"]) == (1 / 3, 1 / 3, 1 / 3)
    assert (b["score_dead"], b["score_late"], b["score_moved"]) == (0.5, 0.75, 1.0)
    assert b["moves"] == 7
    assert (b["still"], b["small"], b["back"], b["limit"]) == (3 / 7, 1 / 7, 1 / 7, 1 / 7)
    d = rows["drawer"]
    assert (d["moved"], d["score_moved"], d["score_dead"], d["back"]) == (1.0, 1.0, None, 1.0)
    table = run(str(tmp_path / "run"))
    assert table.returncode == 0 and table.stdout.splitlines()[2].startswith("Box | 4 | 0.75 | 0.33"), table.stdout


def test_a_folder_that_is_not_a_run_or_lacks_the_policy_is_named(tmp_path):
    p = run(str(tmp_path))
    assert p.returncode != 0 and str(tmp_path) in p.stderr and "results.json" in p.stderr
    write_run(tmp_path / "run", [])
    p = run(str(tmp_path / "run"), "--policy", "where2act")
    assert p.returncode != 0 and "`where2act`" in p.stderr
