"""Descriptive controls: the thesis's named sliders (Table 6.2) as a data table over muscle channels.

Each of the 14 rows drives one muscle: "Smile/Wide" is the zygomatic major, "Lower Brows" the
procerus. Paired rows hold two sliders, one per side, read with the thesis's mirror convention:
the LEFT slider drives the face's RIGHT side (``_R``) and the right slider the face's left side
(``_L``), as in a mirror, where the face's right side appears on the viewer's left. Single rows
(procerus, mentalis) hold one value. The table lives in ``data/descriptive_controls.json``.
"""

from __future__ import annotations

import difflib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

from mimetic.errors import ControlError
from mimetic.rig.activations import pose
from mimetic.rig.model import Channel, Rig

Setting = float | tuple[float, float]


@dataclass(frozen=True)
class DescriptiveControl:
    """One row of the descriptive tab: a named slider (or slider pair) driving one muscle.

    Attributes
    ----------
    name : str
        The thesis's label, e.g. "Smile/Wide".
    muscle : str
        The muscle channel without its side, e.g. "zygomatic_major" (or "procerus").
    paired : bool
        True for a left/right pair of sliders.
    description : str
        What the muscle does, with its FACS action unit.
    """

    name: str
    muscle: str
    paired: bool
    description: str = ""

    @property
    def channels(self) -> tuple[str, ...]:
        """Channels in slider order: (left slider's, right slider's) = ``(muscle_R, muscle_L)``."""
        return (f"{self.muscle}_R", f"{self.muscle}_L") if self.paired else (self.muscle,)

    def values(self, setting: Setting) -> dict[str, float]:
        """Channel values of a slider setting: a number, or (left slider, right slider) for a pair.

        A single number on a paired row sets both sides.
        """
        if isinstance(setting, (str, bytes)):
            raise ControlError(f"{self.name!r}: expected a number, got {setting!r}")
        sliders = np.atleast_1d(np.asarray(setting, dtype=object))
        if sliders.ndim != 1 or len(sliders) not in ((1, 2) if self.paired else (1,)):
            shape = "a number or (left slider, right slider)" if self.paired else "one number"
            raise ControlError(f"{self.name!r} takes {shape}; got {setting!r}")
        try:
            numbers = [float(x) for x in sliders]
        except (TypeError, ValueError):
            raise ControlError(f"{self.name!r}: slider values must be numbers; got {setting!r}") from None
        if len(numbers) == 1:
            numbers = numbers * len(self.channels)
        for slider, number in zip(("left", "right") if self.paired else ("",), numbers, strict=False):
            if not np.isfinite(number):
                where = f"{slider} slider" if slider else "value"
                raise ControlError(f"{self.name!r}: {where} {number} is not finite")
        return dict(zip(self.channels, numbers, strict=True))

    def read(self, values: Mapping[str, float]) -> Setting:
        """The slider setting that shows channel ``values`` (missing channels read 0)."""
        sliders = tuple(float(values.get(c, 0.0)) for c in self.channels)
        return sliders if self.paired else sliders[0]


@cache
def descriptive_controls() -> tuple[DescriptiveControl, ...]:
    """The 14 descriptive controls of the thesis (Table 6.2), in the tab's row order (Fig. 6.15)."""
    text = resources.files("mimetic.animate").joinpath("data/descriptive_controls.json").read_text("utf-8")
    return tuple(
        DescriptiveControl(row["name"], row["muscle"], bool(row["paired"]), row.get("description", ""))
        for row in json.loads(text)["controls"]
    )


def descriptive_control(name: str) -> DescriptiveControl:
    """The control called ``name`` (exact label, e.g. "Smile/Wide"); ControlError with suggestions."""
    controls = {c.name: c for c in descriptive_controls()}
    if name in controls:
        return controls[name]
    folded = {c.name.casefold(): c for c in descriptive_controls()}
    close = difflib.get_close_matches(name.casefold(), list(folded), n=3, cutoff=0.5)
    hint = (
        f"did you mean {', '.join(repr(folded[c].name) for c in close)}?"
        if close
        else f"the controls are {', '.join(repr(c) for c in controls)}"
    )
    raise ControlError(f"unknown descriptive control {name!r}; {hint}")


def apply_descriptive(rig: Rig | Sequence[Channel], settings: Mapping[str, Setting]) -> dict[str, float]:
    """Channel values from descriptive slider settings.

    Parameters
    ----------
    rig : Rig or sequence of Channel
        The channels the values are for; each control's channels must exist, and each value must
        lie in its channel's range (muscles: [0, 1]).
    settings : Mapping[str, float | (float, float)]
        Control name → a number for single rows (or both sides of a pair), or
        ``(left slider, right slider)`` for paired rows; the left slider drives ``_R``, e.g.
        ``{"Smile/Wide": (0.4, 1.0)}`` → ``{"zygomatic_major_R": 0.4, "zygomatic_major_L": 1.0}``.

    Returns
    -------
    values : dict[str, float]
        Channel name → value, for ``mimetic.rig.activations.pose``.
    """
    channels = {c.name: c for c in (rig.channels if isinstance(rig, Rig) else rig)}
    out: dict[str, float] = {}
    for name, setting in settings.items():
        control = descriptive_control(name)
        values = control.values(setting)
        for slider, (channel, value) in zip(("left", "right"), values.items(), strict=False):
            if channel not in channels:
                raise ControlError(f"{name!r} drives channel {channel!r}, which this rig does not have")
            c = channels[channel]
            if not c.minimum - 1e-9 <= value <= c.maximum + 1e-9:
                where = f"{slider} slider" if control.paired else "value"
                raise ControlError(
                    f"{name!r}: {where} {value:g} is outside [{c.minimum:g}, {c.maximum:g}] ({channel})"
                )
        out.update(values)
    return out


def descriptive_pose(rig: Rig, settings: Mapping[str, Setting]) -> np.ndarray:
    """A pose (c,) float64: the rig's defaults with the channels of ``settings`` set.

    See ``apply_descriptive`` for the settings and the mirror convention.
    """
    return pose(rig, apply_descriptive(rig, settings))


def read_descriptive(rig: Rig | Sequence[Channel], values: np.ndarray) -> dict[str, Setting]:
    """The slider settings (control name → number or (left, right)) that show a pose (c,)."""
    names = [c.name for c in (rig.channels if isinstance(rig, Rig) else rig)]
    by_name = dict(zip(names, np.asarray(values, dtype=np.float64).tolist(), strict=True))
    return {c.name: c.read(by_name) for c in descriptive_controls()}
