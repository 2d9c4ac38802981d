"""A pytest plugin `make test` loads (-p skipguard): under CI=true a skipped
test fails the run, unless its reason contains one of the texts listed in
UMPNET_EXPECTED_SKIPS (separated by ';'). A skip is a test that did not run;
in CI that must be a decision, not an accident of the environment."""

from __future__ import annotations

import os


def unexpected_skips(reports, expected: list[str]) -> list:
    return [r for r in reports if not any(e in str(r.longrepr) for e in expected)]


def pytest_sessionfinish(session, exitstatus):
    if os.environ.get("CI") != "true":
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is None:
        return
    expected = [e for e in os.environ.get("UMPNET_EXPECTED_SKIPS", "").split(";") if e]
    found = unexpected_skips(reporter.stats.get("skipped", []), expected)
    for r in found:
        reporter.write_line(f"unexpected skip under CI=true: {r.nodeid}: {r.longrepr}", red=True)
    if found:
        session.exitstatus = 1
