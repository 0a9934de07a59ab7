"""Fixtures the viewer's tests share."""

from __future__ import annotations

import pytest

from mimetic.rig.format import save_rig


@pytest.fixture(scope="module")
def rig_file(rig, tmp_path_factory):
    """The session's small rig saved as a .mrig file the viewer opens."""
    return save_rig(rig, tmp_path_factory.mktemp("rig") / "small.mrig")
