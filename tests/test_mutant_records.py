"""scripts/cargo_mutants.py --check: a record counts only if it is of the
current sources, and its survivors must be exactly the listed harmless ones."""

import importlib.util
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "cargo_mutants.py"


@pytest.fixture
def cm(tmp_path, monkeypatch):
    spec = importlib.util.spec_from_file_location("cargo_mutants", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "cargo_mutants", mod)  # dataclasses look their module up
    spec.loader.exec_module(mod)
    monkeypatch.setattr(mod, "ROOT", tmp_path)
    monkeypatch.setattr(mod, "RECORDS", tmp_path / "records")
    monkeypatch.setattr(mod, "HARMLESS", tmp_path / "harmless.txt")
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "a.rs").write_text("fn a() -> bool { 1 < 2 }\n")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "t.rs").write_text("#[test] fn t() {}\n")
    (tmp_path / "harmless.txt").write_text("# comment\nsrc/a.rs: replace < with <= in a -- never equal\n")
    group = mod.Group("g", "crate", ["src/a.rs"], ["tests/t.rs"])
    out = group.folder / "mutants.out"
    out.mkdir(parents=True)
    outcomes = {
        "caught": ["src/a.rs:1:20: replace a -> bool with true"],
        "missed": ["src/a.rs:1:20: replace < with <= in a"],
    }
    for o in mod.OUTCOMES:
        (out / f"{o}.txt").write_text("".join(f"{line}\n" for line in outcomes.get(o, [])))
    # The record a full run writes, without asking cargo for its version.
    monkeypatch.setattr(mod.subprocess, "run", lambda *a, **k: type("P", (), {"stdout": "cargo-mutants 0"})())
    mod.write_record(group, mod.digests(group))
    return mod, group, tmp_path


def test_a_record_of_the_current_sources_with_listed_survivors_passes(cm):
    mod, group, _ = cm
    text = group.record.read_text()
    assert "# caught 1, missed 1, timeout 0, unviable 0" in text
    assert "missed src/a.rs: replace < with <= in a" in text
    assert mod.check([group]) == 0


@pytest.mark.parametrize("edited", ["src/a.rs", "tests/t.rs"])
def test_a_record_of_other_sources_fails_and_names_the_file(cm, capsys, edited):
    mod, group, root = cm
    with (root / edited).open("a") as f:
        f.write("// edited\n")
    assert mod.check([group]) == 1
    assert f"of other sources ({edited})" in capsys.readouterr().out


def test_an_unlisted_survivor_and_a_stale_entry_both_fail(cm, capsys):
    mod, group, root = cm
    (root / "harmless.txt").write_text("src/a.rs: replace > with >= in a -- a reason\n")
    assert mod.check([group]) == 1
    out = capsys.readouterr().out
    assert "missed and not explained: src/a.rs: replace < with <= in a" in out
    assert "no longer missed" in out and "replace > with >= in a" in out


def test_an_entry_without_a_reason_and_a_missing_record_are_refused(cm):
    mod, group, root = cm
    (root / "harmless.txt").write_text("src/a.rs: replace < with <= in a\n")
    with pytest.raises(SystemExit, match="gives no reason"):
        mod.check([group])
    group.record.unlink()
    with pytest.raises(SystemExit, match="no record"):
        mod.check([group])
