"""Retargeting and editing solved performances (the paper's §4).

Retargeting is by channel name: the same activation curves drive any rigged head, each through its
own muscles (``retarget``). Editing uses the clip layers of ``mimetic.animate.keyframes``: a solved clip
becomes the base layer of a ``KeyframeClip`` (``from_clip``), B-spline displacement edits go in
additive layers (``KeyframeClip.edit``, the paper's expression displacement mapping), and after a
re-solve ``keep_edits`` swaps in the new base under the same edits.
"""

from __future__ import annotations

import warnings

import numpy as np

from mimetic.animate.keyframes import KeyframeClip, from_clip
from mimetic.errors import MimeticWarning
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig


def retarget(clip: Clip, rig: Rig) -> Clip:
    """``clip`` on ``rig``'s channels: matched by name, the rig's others at their defaults, values
    clipped to the rig's ranges (a warning says how many channels and samples were changed)."""
    index = {n: j for j, n in enumerate(clip.channels)}
    dropped = [n for n in clip.channels if n not in set(rig.channel_names)]
    values = np.empty((clip.n_frames, len(rig.channels)))
    clipped = []
    for j, ch in enumerate(rig.channels):
        if ch.name not in index:
            values[:, j] = ch.default
            continue
        column = clip.values[:, index[ch.name]]
        values[:, j] = np.clip(column, ch.minimum, ch.maximum)
        if np.any(values[:, j] != column):
            clipped.append(ch.name)
    moving = [n for n in dropped if np.any(clip.values[:, index[n]] != 0)]
    if moving or clipped:
        parts = []
        if moving:
            parts.append(f"the rig has no channel(s) {', '.join(moving[:5])} (dropped)")
        if clipped:
            parts.append(f"{', '.join(clipped[:5])} went outside the rig's ranges (clipped)")
        warnings.warn("retarget: " + "; ".join(parts), MimeticWarning, stacklevel=2)
    return Clip(rig.channel_names, values, clip.fps)


def keep_edits(edited: KeyframeClip, solved: Clip) -> KeyframeClip:
    """``edited`` with its base layer replaced by a new solve, every edit layer kept."""
    base = from_clip(solved, name=edited.base.name).base
    return edited.with_base(base, duration_s=(solved.n_frames - 1) / solved.fps)
