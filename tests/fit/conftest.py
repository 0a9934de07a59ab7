"""Fixtures shared by the fit tests."""

from __future__ import annotations

import os

import numpy as np
import pytest

from mimetic.errors import MissingExtraError
from mimetic.head.model import Head, make_head
from mimetic.head.params import HeadParams

ON_CI = os.environ.get("CI", "").lower() == "true"


@pytest.fixture(scope="module")
def mediapipe_ready() -> None:
    """Skip when the [track] extra is missing, except on CI (CI=true), where it fails."""
    from mimetic.fit.detect import detect_face

    try:
        detect_face(np.zeros((8, 8, 3), np.uint8))
    except MissingExtraError as error:
        if ON_CI:
            pytest.fail(f"{error} (CI=true: the [track] extra is required on CI)")
        pytest.skip(str(error))


@pytest.fixture(scope="module")
def heads():
    """``heads(seed) -> Head`` at the default resolution, built once per module (None: the default head)."""
    cache: dict[int | None, Head] = {}

    def get(seed: int | None) -> Head:
        if seed not in cache:
            cache[seed] = make_head() if seed is None else make_head(HeadParams.random(seed))
        return cache[seed]

    return get
