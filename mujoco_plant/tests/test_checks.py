"""The physical self-checks of tilting_mujoco.checks, one test each (skipped without mujoco)."""

import pytest

pytest.importorskip("mujoco")

from tilting_mujoco import checks  # noqa: E402


@pytest.mark.parametrize("check", checks.CHECKS, ids=lambda c: c.__name__)
def test_check(check):
    print(check())
