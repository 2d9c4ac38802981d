"""Fixtures shared by every test suite in the repository (tests/, crates/py/tests)."""

import os

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
