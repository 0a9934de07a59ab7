"""The muscle overlay draws every muscle whole, where the rig says it is."""

from __future__ import annotations

import numpy as np

from mimetic.view.muscles import muscle_segments


def test_muscle_segments_draw_each_muscle_whole_on_its_attachments(rig):
    rest = rig.mesh.vertices.copy()
    segments, colors, ring = muscle_segments(rig, ring_segments=24)
    assert segments.dtype == np.float64 and segments.shape[1:] == (2, 3)
    assert colors.shape == (len(segments), 3) and ring.shape == (len(segments),)
    v, f = rig.mesh.vertices, rig.mesh.faces
    lines = iter(segments[~ring])
    rings = segments[ring].reshape(-1, 24, 2, 3)
    k = 0
    for m in rig.muscles:
        if m.kind == "sphincter":
            loop = rings[k]
            k += 1
            np.testing.assert_allclose(loop[1:, 0], loop[:-1, 1], atol=1e-12)  # joined ...
            np.testing.assert_allclose(loop[0, 0], loop[-1, 1], atol=1e-9)  # ... and closed
            centre = m.origin.position(v, f)
            np.testing.assert_allclose(loop[:, 0].mean(axis=0), centre, atol=1e-9 * rig.scale)
            reach = np.linalg.norm(loop[:, 0] - centre, axis=1).max()
            np.testing.assert_allclose(reach, np.linalg.norm(m.insertion.position(v, f) - centre), rtol=1e-9)
        else:
            start, end = next(lines)
            np.testing.assert_allclose(start, rig.muscle_attachment(m.name), atol=1e-12)
            np.testing.assert_allclose(end, m.insertion.position(v, f), atol=1e-12)
    assert k == len(rings) and next(lines, None) is None  # nothing left over: one drawing per muscle
    np.testing.assert_array_equal(rig.mesh.vertices, rest)
