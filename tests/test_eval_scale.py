"""`umpnet eval` at any size: episodes stream to episodes.jsonl, memory stays
flat as episodes grow, an interrupted run resumes to the report of an
uninterrupted one, and `eval merge` streams many shards."""

import json
import os
import re
import signal
import subprocess
import time
from pathlib import Path

from umpnet_cli import UMPNET

REPORT = ("episodes.jsonl", "results.csv", "results.md", "results.tex", "table.txt", "curve.png", "curve.svg")


def peak_rss_mb(args: list[str], timeout: float = 600) -> tuple[float, subprocess.CompletedProcess]:
    """Runs umpnet and returns its own peak resident memory (MB), from wait4."""
    p = subprocess.Popen([UMPNET, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + timeout
    while True:
        pid, status, usage = os.wait4(p.pid, os.WNOHANG)
        if pid:
            break
        if time.monotonic() > deadline:
            p.kill()
            raise TimeoutError(args)
        time.sleep(0.05)
    out, err = p.stdout.read(), p.stderr.read()
    done = subprocess.CompletedProcess(args, os.waitstatus_to_exitcode(status), out, err)
    return usage.ru_maxrss / 1024, done


def without_wall_time(path: Path) -> bytes:
    return re.sub(rb'"wall_seconds":[-0-9.eE+]+', b"", path.read_bytes())


def test_memory_stays_flat_as_episodes_grow_tenfold(tmp_path):
    common = ["--json", "eval", "--categories", "Door", "--policies", "random", "--renderer", "cpu"]
    rss = {}
    for n in (40, 400):
        rss[n], p = peak_rss_mb([*common, "--episodes-per-category", str(n), "--out", str(tmp_path / str(n))])
        assert p.returncode == 0, p.stderr
        assert json.loads(p.stdout)["episodes"] == 2 * n  # random and the oracle
        lines = (tmp_path / str(n) / "episodes.jsonl").read_text().splitlines()
        assert len(lines) == 2 * n
    # Holding the episodes (about 100 KB each before streaming) would add ~70 MB here.
    assert rss[400] < rss[40] + 10 and rss[400] < 150, rss


def test_a_killed_run_resumes_to_the_uninterrupted_report(tmp_path):
    common = ["eval", "--task", "goal", "--categories", "Door,Laptop,Box", "--episodes-per-category", "40"]
    common += ["--policies", "random", "--renderer", "cpu", "--threads", "2"]
    whole = tmp_path / "whole"
    subprocess.run([UMPNET, *common, "--out", str(whole)], check=True, capture_output=True, timeout=600)
    for sig in (signal.SIGKILL, signal.SIGTERM):
        out = tmp_path / sig.name
        p = subprocess.Popen([UMPNET, *common, "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        episodes = out / "episodes.jsonl"
        deadline = time.monotonic() + 120
        while not (episodes.exists() and episodes.stat().st_size > 0) and time.monotonic() < deadline:
            time.sleep(0.02)
        p.send_signal(sig)
        _, err = p.communicate(timeout=120)
        assert not (out / "results.json").exists(), "the run finished before it was stopped"
        if sig == signal.SIGTERM:
            # Stopped cleanly: whole lines only, and it says how to go on.
            assert p.returncode == 130 and b"--resume continues" in err, err
            assert episodes.read_bytes().endswith(b"\n")
            assert not (out / ".umpnet.lock").exists()
        else:
            assert p.returncode == -signal.SIGKILL
        written = len(episodes.read_bytes().splitlines())
        assert 0 < written < 240
        # Without --resume the folder is not silently restarted.
        again = subprocess.run([UMPNET, *common, "--out", str(out)], capture_output=True, text=True, check=False)
        assert again.returncode == 2 and "--resume" in again.stderr, again.stderr
        # Not the same evaluation: refused, by field.
        other = subprocess.run(
            [UMPNET, *common, "--seed", "5", "--out", str(out), "--resume"], capture_output=True, text=True, check=False
        )
        assert other.returncode == 2 and "seed (5 against 0)" in other.stderr, other.stderr
        subprocess.run([UMPNET, *common, "--out", str(out), "--resume"], check=True, capture_output=True, timeout=600)
        for name in REPORT:
            assert (out / name).read_bytes() == (whole / name).read_bytes(), (sig.name, name)
        assert without_wall_time(out / "results.json") == without_wall_time(whole / "results.json")
        done = subprocess.run(
            [UMPNET, *common, "--out", str(out), "--resume"], capture_output=True, text=True, check=False
        )
        assert done.returncode == 2 and "nothing to resume" in done.stderr


def test_merge_streams_many_shards_in_flat_memory(tmp_path):
    common = ["--json", "eval", "--categories", "Door,Microwave", "--episodes-per-category", "60"]
    common += ["--policies", "random", "--renderer", "cpu", "--threads", "1"]
    subprocess.run([UMPNET, *common, "--out", str(tmp_path / "whole")], check=True, capture_output=True)
    n = 120
    shards = []
    for k in range(1, n + 1):
        d = tmp_path / "shards" / str(k)
        subprocess.run([UMPNET, *common, "--shard", f"{k}/{n}", "--out", str(d)], check=True, capture_output=True)
        shards.append(str(d))
    rss, p = peak_rss_mb(["eval", "merge", *shards, "--out", str(tmp_path / "merged")])
    assert p.returncode == 0, p.stderr
    for name in REPORT:
        assert (tmp_path / "merged" / name).read_bytes() == (tmp_path / "whole" / name).read_bytes(), name
    assert rss < 100, rss
    # A shard whose episodes were changed after its summary was written is refused.
    victim = Path(shards[7]) / "episodes.jsonl"
    victim.write_text(victim.read_text().replace('"index":', '"index": ', 1))
    p = subprocess.run([UMPNET, "eval", "merge", *shards], capture_output=True, text=True, check=False)
    assert p.returncode == 2 and "8/120" in p.stderr and "SHA-256" in p.stderr, p.stderr
    # ...and one cut short is named, with how many episodes it has.
    victim.write_text("\n".join(victim.read_text().splitlines()[:-1]) + "\n")
    p = subprocess.run([UMPNET, "eval", "merge", *shards], capture_output=True, text=True, check=False)
    assert p.returncode == 2 and "ends after" in p.stderr, p.stderr
