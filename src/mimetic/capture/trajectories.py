"""Tracked points over time: markers from a mocap system, landmarks from a face tracker.

A ``Trajectories`` is what every capture reader returns and every capture step consumes:
positions (frames, points, d) with NaN where a point was not seen, the point names, the frame
rate, the length unit and a per-frame confidence. ``d`` is 3 for markers and lifted landmarks,
2 for image-plane landmarks (pixels, +y down as images are stored).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from mimetic.errors import MimeticError

LENGTH_UNITS = ("mm", "cm", "m", "px")
"""Units a trajectory may be in: lengths, or pixels for image landmarks; None when unknown."""


class CaptureError(MimeticError, ValueError):
    """Capture input that cannot be used: a corrupt or unknown marker file, markers that never
    appear, too few markers for the channels, a frame rate or unit that contradicts the file."""


@dataclass(frozen=True, eq=False)
class Trajectories:
    """Named points tracked over frames.

    Arrays are read-only.

    Attributes
    ----------
    names : tuple of str, (m,)
        Unique point names (e.g. "ibug68_48", "mediapipe_61", or a mocap marker's label).
    positions : (f, m, d) float64
        d = 3 (x, y, z) or 2 (image x, y); NaN where a point is missing in a frame. Never ±inf.
    fps : float
        Frames per second, > 0.
    units : str or None
        One of ``LENGTH_UNITS``, or None when the source does not say.
    confidence : (f,) float64
        Per-frame tracking confidence in [0, 1] (1 where the source gives none; 0 for a frame in
        which the tracker found no face).
    source : str
        Where the data came from (a path, "synthetic", …), for messages.
    tracked : bool
        The points are a face tracker's landmarks (a video's, OpenFace's), not markers on the skin:
        a contour landmark (the jaw line, the face's oval) is where the face's outline is seen, and
        slides over the skin as the head turns.
    image_size : (2,) int or None
        Width and height of the images the points were found in (pixels), when ``units`` is "px".
    """

    names: tuple[str, ...]
    positions: np.ndarray
    fps: float
    units: str | None = None
    confidence: np.ndarray | None = None
    source: str = "trajectories"
    tracked: bool = False
    image_size: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        names = tuple(str(n) for n in self.names)
        if len(set(names)) != len(names):
            repeated = sorted({n for n in names if names.count(n) > 1})
            raise CaptureError(
                f"{self.source}: point names repeat ({', '.join(repeated[:5])}); names must be unique"
            )
        positions = np.array(self.positions, dtype=np.float64)
        if positions.ndim != 3 or positions.shape[1] != len(names) or positions.shape[2] not in (2, 3):
            raise CaptureError(
                f"{self.source}: positions must have shape (frames, {len(names)}, 3) or "
                f"(frames, {len(names)}, 2); got {positions.shape}"
            )
        if np.isinf(positions).any():
            t, j, _ = np.argwhere(np.isinf(positions))[0]
            raise CaptureError(
                f"{self.source}: point {names[j]!r} is infinite at frame {t}; use NaN for a missing point"
            )
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise CaptureError(f"{self.source}: fps must be a positive number; got {self.fps}")
        if self.units is not None and self.units not in LENGTH_UNITS:
            raise CaptureError(
                f"{self.source}: units {self.units!r} unknown; use one of {', '.join(LENGTH_UNITS)}"
            )
        f = len(positions)
        if self.confidence is None:
            confidence = np.ones(f)
        else:
            confidence = np.array(self.confidence, dtype=np.float64).reshape(-1)
            if confidence.shape != (f,) or not np.all((confidence >= 0) & (confidence <= 1)):
                raise CaptureError(
                    f"{self.source}: confidence must be ({f},) numbers in [0, 1]; "
                    f"got shape {confidence.shape}"
                )
        positions.setflags(write=False)
        confidence.setflags(write=False)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "fps", float(self.fps))
        object.__setattr__(self, "confidence", confidence)
        if self.image_size is not None:
            object.__setattr__(self, "image_size", (int(self.image_size[0]), int(self.image_size[1])))

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_points(self) -> int:
        return self.positions.shape[1]

    @property
    def dims(self) -> int:
        """2 for image-plane landmarks, 3 for markers and lifted landmarks."""
        return self.positions.shape[2]

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    @property
    def seen(self) -> np.ndarray:
        """(f, m) bool: the point has finite coordinates in the frame."""
        return np.isfinite(self.positions).all(axis=2)

    def select(self, names: Sequence[str]) -> Trajectories:
        """The named points, in that order; a name the trajectories lack raises ``CaptureError``."""
        index = {n: j for j, n in enumerate(self.names)}
        missing = [n for n in names if n not in index]
        if missing:
            raise CaptureError(
                f"{self.source}: no point(s) {', '.join(missing[:5])}; it has {', '.join(self.names[:6])}, …"
            )
        columns = [index[n] for n in names]
        return replace(self, names=tuple(names), positions=self.positions[:, columns])

    def frames(self, start: int, stop: int | None = None) -> Trajectories:
        """Frames ``start:stop`` (Python slice semantics)."""
        keep = slice(start, stop)
        return replace(self, positions=self.positions[keep], confidence=self.confidence[keep])
