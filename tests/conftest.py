"""Shared pytest helpers for the attica tests."""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

# The development tooling (golden, cross, footprint, bench) lives in tools/attica_dev, outside the
# installed package; the tests import it from the checkout.
_TOOLS = str(Path(__file__).resolve().parent.parent / "tools")
if _TOOLS not in sys.path:
    sys.path.insert(0, _TOOLS)


def require_tool(name: str) -> str:
    """Return the path of program ``name``; skip the test when it is missing (fail in CI).

    In CI (environment ``CI=true``) a missing tool is an error, so a gate can never pass by
    silently skipping there.
    """
    path = shutil.which(name)
    if path is None:
        reason = f"{name} is not installed (host/tools/install-system-deps.sh installs it)"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{reason}; CI=true, so this is an error, not a skip")
        print(f"SKIP: {reason}")
        pytest.skip(reason)
    return path


@pytest.fixture(name="require_tool")
def require_tool_fixture() -> Callable[[str], str]:
    """:func:`require_tool` as a fixture, for tests that prefer not to import conftest."""
    return require_tool
