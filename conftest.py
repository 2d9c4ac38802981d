"""Fixtures shared by every test suite in the repository (tests/, crates/py/tests)."""

import os
import shutil
from pathlib import Path

import pytest


@pytest.fixture
def fixture_package() -> str:
    """The contract-test package (`make fixture`). Without it the test is
    skipped with the reason, except in CI (CI=true), where that is a failure."""
    path = os.environ.get("UMPNET_FIXTURE")
    if not path:
        why = "UMPNET_FIXTURE not set (make test sets it)"
        if os.environ.get("CI") == "true":
            pytest.fail(why)
        pytest.skip(why)
    return path


def _poisoned(package, dest: Path, file: str, output: str, value: float) -> Path:
    """A copy of `package` whose network `file` gives `output` times `value`."""
    import onnx
    from onnx import helper

    shutil.copytree(package, dest)
    model = onnx.load(str(dest / file))
    graph = model.graph
    inner = f"{output}_clean"
    for node in graph.node:
        node.output[:] = [inner if o == output else o for o in node.output]
    graph.node.append(helper.make_node("Constant", [], ["poison"], value_float=value))
    graph.node.append(helper.make_node("Mul", [inner, "poison"], [output]))
    onnx.save(model, str(dest / file))
    return dest


@pytest.fixture
def poisoned_package():
    """`poisoned_package(package, dest, file, output, value)`: a copy of a
    model package with one network output multiplied by `value` (NaN, inf, a
    negative number), to test that the runtime refuses what it gives."""
    return _poisoned
