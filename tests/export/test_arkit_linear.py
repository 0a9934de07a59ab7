"""ARKit weights land linearly through the wire engine: a shape posed at weight w (``arkit_pose``) reads
back as w with the reverse map (``arkit_weights``'s fit of the baked 52 shapes)."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.animate.arkit import ARKIT_NAMES, arkit_pose, arkit_table
from mimetic.engines import make_engine
from mimetic.export.arkit import arkit_shapes, prepare_arkit_fit
from mimetic.testing import small_rig

WEIGHTS = (0.25, 0.5, 0.75)
GOAL_MEDIAN = 0.03  # issue 11; measured 0.000 and 0.018 here (thesis formula: 0.035 and 0.19)
GOAL_P95 = 0.08


@pytest.fixture(scope="module")
def engine():
    return make_engine(small_rig(), "wire")


def _independent(engine, name: str) -> bool:
    """Does the shape drive one muscle channel, or muscles that share no wire control point?"""
    shape = arkit_table()[name]
    values = dict(shape.values)
    for channel, value in arkit_table()[shape.pair].values.items() if shape.pair else ():
        values[channel] = values.get(channel, 0.0) + value
    rig = engine.rig
    muscles = [rig.channel_index(c) for c in values if rig.channel(c).unit == "activation"]
    return not ((engine.weights[:, muscles] > 0).sum(axis=1) > 1).any()


def test_arkit_weights_read_back_as_posed_through_the_wire_engine(engine):
    """Each supported shape whose muscles pull separate control points, alone (a split shape with its
    pair: alone it moves both sides by half), at 0.25, 0.5 and 0.75, reads back within the issue's
    targets. The thesis's saturating constraint read 0.5 as 0.67 (mouthSmileLeft) and failed both."""
    rig = engine.rig
    rest = engine.deform(np.array([c.default for c in rig.channels]))
    fit = prepare_arkit_fit(arkit_shapes(engine))
    table = arkit_table()
    names = [n for n in ARKIT_NAMES if table[n].status != "unsupported" and _independent(engine, n)]
    assert len(names) >= 30
    cases = [(n, w) for n in names for w in WEIGHTS]
    poses = [arkit_pose(rig, {n: w} | ({table[n].pair: w} if table[n].pair else {})) for n, w in cases]
    read = fit.solve(np.array([engine.deform(p) - rest for p in poses]))  # (cases, 52)
    assert read.shape == (len(cases), 52) and read.dtype == np.float64
    error = np.array([read[k, ARKIT_NAMES.index(n)] - w for k, (n, w) in enumerate(cases)])
    assert np.median(np.abs(error)) <= GOAL_MEDIAN
    assert np.percentile(np.abs(error), 95) <= GOAL_P95
    # one muscle alone lands exactly: a smile at half weight is half a smile
    k = cases.index(("mouthSmileLeft", 0.5))
    assert read[k, ARKIT_NAMES.index("mouthSmileLeft")] == pytest.approx(0.5, abs=0.005)
