"""Conformation parameters of the parametric reference head (in the spirit of Parke's face).

Every parameter is a dimensionless factor; 1.0 (or 0.0 for offsets) is the default head.
Lengths that the factors scale are given below relative to the default head height
(vertex to menton, 21.6 cm), so ``nose_length = 1.1`` makes the nose 10 % longer than the
default 5.6 cm (0.26 of the head height). The lengths are measured between the head's own
landmarks.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from mimetic.errors import MimeticError

# name: (minimum, maximum, what it scales, default length relative to head height)
PARAM_RANGES: dict[str, tuple[float, float, str]] = {
    "head_width": (0.90, 1.10, "skull and face width (0.73 of head height)"),
    "head_height": (0.92, 1.08, "vertical size of the whole head (1.0 of head height)"),
    "head_depth": (
        0.92,
        1.08,
        "front-to-back depth, glabella to the back of the skull (0.91 of head height)",
    ),
    "jaw_width": (0.85, 1.15, "bigonial width at the jaw angles (0.54 of head height)"),
    "chin_height": (0.80, 1.20, "stomion-to-menton height (0.18 of head height)"),
    "nose_length": (0.90, 1.10, "nasion-to-subnasale length (0.26 of head height)"),
    "nose_width": (0.80, 1.25, "alar width (0.17 of head height)"),
    "nose_projection": (0.85, 1.15, "nose tip in front of the nasion (0.11 of head height)"),
    "upper_lip": (0.70, 1.30, "upper vermilion height (0.031 of head height)"),
    "lower_lip": (0.70, 1.30, "lower vermilion height (0.042 of head height)"),
    "mouth_width": (0.85, 1.15, "corner-to-corner mouth width (0.24 of head height)"),
    "eye_spacing": (0.92, 1.08, "inter-pupil distance (0.29 of head height)"),
    "eye_size": (0.90, 1.10, "palpebral fissure (0.12 of head height) and eyeball size"),
    "brow_ridge": (0.50, 1.50, "brow-ridge prominence (0.018 of head height)"),
    "cheekbones": (0.50, 1.50, "zygomatic prominence (0.014 of head height)"),
}


class HeadParamError(MimeticError, ValueError):
    """An unknown head parameter or a value outside its documented range."""


@dataclass(frozen=True)
class HeadParams:
    """Conformation of a generated head; see ``PARAM_RANGES`` for meaning and range."""

    head_width: float = 1.0
    head_height: float = 1.0
    head_depth: float = 1.0
    jaw_width: float = 1.0
    chin_height: float = 1.0
    nose_length: float = 1.0
    nose_width: float = 1.0
    nose_projection: float = 1.0
    upper_lip: float = 1.0
    lower_lip: float = 1.0
    mouth_width: float = 1.0
    eye_spacing: float = 1.0
    eye_size: float = 1.0
    brow_ridge: float = 1.0
    cheekbones: float = 1.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            lo, hi, _ = PARAM_RANGES[f.name]
            if not (np.isfinite(value) and lo - 1e-9 <= value <= hi + 1e-9):
                raise HeadParamError(f"head parameter {f.name}={value} is outside its range [{lo}, {hi}]")

    @staticmethod
    def random(seed: int | None = None, *, spread: float = 1.0) -> HeadParams:
        """Varied, plausible parameters: each factor drawn from a clipped normal around its default.

        ``spread`` scales the standard deviation (1.0: half of the half-range), so about one
        face in ten has some parameter near the end of its range.
        """
        rng = np.random.default_rng(seed)
        values = {}
        for name, (lo, hi, _) in PARAM_RANGES.items():
            default = getattr(HeadParams, name)
            half = min(default - lo, hi - default)
            values[name] = float(np.clip(default + rng.normal(0.0, spread * half / 2.0), lo, hi))
        return HeadParams(**values)

    def with_values(self, **values: float) -> HeadParams:
        """A copy with some parameters changed; unknown names raise ``HeadParamError``."""
        unknown = sorted(set(values) - set(PARAM_RANGES))
        if unknown:
            raise HeadParamError(f"unknown head parameter(s) {unknown}; known: {', '.join(PARAM_RANGES)}")
        return replace(self, **values)

    def as_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}
