"""Where the shared real test data lives (ICT-FaceKit, MediaPipe, speech, landmarks).

Not shipped with the package: tests, benchmarks and the demo use it when it is beside the
repository (``../shared/data``, the layout on CI and in development) or named by
``$MIMETIC_SHARED_DATA``.
"""

from __future__ import annotations

import os
from pathlib import Path

SHARED_DATA_ENV = "MIMETIC_SHARED_DATA"


def shared_data_dir() -> Path | None:
    """The shared data folder (it holds a ``README.md``), or None when absent."""
    env = os.environ.get(SHARED_DATA_ENV)
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[3] / "shared" / "data")
    return next((c for c in candidates if (c / "README.md").is_file()), None)
