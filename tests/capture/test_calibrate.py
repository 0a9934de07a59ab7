"""Per-performer calibration: the similarity (units, axes, mirror check) and marker placement, against
captures made from known transforms of the rig's own skin."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimetic.capture import CaptureError, marker_set
from mimetic.capture.calibrate import calibrate_performer
from mimetic.capture.markers import load_marker_set, marker_normals, save_marker_set
from mimetic.errors import MimeticWarning
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.model import SurfacePoint

Z_UP = Rotation.from_euler("x", 90, degrees=True).as_matrix()


@pytest.fixture(scope="module")
def ibug(rig):
    return marker_set(rig, "ibug68")


def performer(rig, ibug, rng, spread: float = 1.0):
    """Markers of a performer whose markers sit up to ``spread`` cm from where the layout puts them (a
    brow stuck higher, a jaw-line point lower): each layout marker moved to a random skin vertex near it
    on skin facing the same way (a marker on the upper lip stays on the upper lip)."""
    skin = rig.mesh.part_vertices("skin")
    normals = vertex_normals(rig.mesh.vertices, rig.mesh.faces)[skin]
    positions, facing = ibug.positions(rig), marker_normals(ibug, rig)
    points = []
    for p, n in zip(positions, facing, strict=True):
        near = skin[(np.linalg.norm(rig.mesh.vertices[skin] - p, axis=1) < spread) & (normals @ n > 0.8)]
        points.append(SurfacePoint.at_vertex(int(rng.choice(near)), rig.mesh.faces))
    return ibug.replace(points=tuple(points))


def test_calibration_recovers_millimetres_z_up_and_the_performers_markers(rig, ibug):
    rng = np.random.default_rng(0)
    truth = performer(rig, ibug, rng)
    shift = np.array([100.0, -20.0, 5.0])
    capture = 10.0 * truth.positions(rig) @ Z_UP.T + shift  # mm, Z-up: the performer's neutral
    calibration = calibrate_performer(rig, ibug, capture, units="mm")
    assert calibration.units == "mm" and calibration.markers.placed
    assert calibration.similarity.scale == pytest.approx(0.1, rel=1e-4)
    np.testing.assert_allclose(calibration.similarity.rotation, Z_UP.T, atol=1e-3)
    placed = calibration.markers.positions(rig)
    error = np.linalg.norm(placed - truth.positions(rig), axis=1)
    layout_error = np.linalg.norm(ibug.positions(rig) - truth.positions(rig), axis=1)
    assert layout_error.max() > 0.5  # the layout was wrong by up to a centimetre ...
    assert error.max() < 0.02  # ... and the placed markers are where the performer's are (cm)
    np.testing.assert_allclose(calibration.moved, np.linalg.norm(placed - ibug.positions(rig), axis=1))
    np.testing.assert_allclose(calibration.reference, truth.positions(rig), atol=0.02)
    assert calibration.usable.all() and np.nanmax(calibration.off_skin) < 0.01
    assert calibrate_performer(rig, ibug, capture, units=None).units == "mm"  # guessed from the size


def test_without_placement_the_markers_stay(rig, ibug):
    capture = 10.0 * ibug.positions(rig)
    calibration = calibrate_performer(rig, ibug, capture, units="mm", place=False)
    assert calibration.markers is ibug and not calibration.moved.any()


def test_a_marker_off_the_face_is_named_and_left_out(rig, ibug):
    capture = ibug.positions(rig).copy()
    capture[30] += np.array([0.0, 0.0, 3.0])  # 3 cm in front of the nose: not on the skin
    with pytest.warns(MimeticWarning, match="ibug68_31"):
        calibration = calibrate_performer(rig, ibug, capture, units="cm")
    assert not calibration.usable[30] and calibration.usable.sum() == 67
    others = np.delete(np.arange(68), 30)
    assert (
        np.linalg.norm(calibration.markers.positions(rig)[others] - ibug.positions(rig)[others], axis=1).max()
        < 0.02
    )


def test_a_mirror_image_and_wrong_units_are_refused(rig, ibug):
    positions = ibug.positions(rig)
    with pytest.raises(CaptureError, match="mirror image"):
        calibrate_performer(rig, ibug, positions * np.array([1.0, 1.0, -1.0]), units="cm")
    with pytest.raises(CaptureError, match="looks like mm"):
        calibrate_performer(rig, ibug, 10.0 * positions, units="m")  # millimetre numbers labelled metres
    too_few = np.full_like(positions, np.nan)
    too_few[:20] = positions[:20]  # only the (sliding) jaw line and three brow points
    with pytest.raises(CaptureError, match="fixed"):
        calibrate_performer(rig, ibug, too_few, units="cm")


def test_placed_markers_round_trip_through_a_marker_file(rig, ibug, tmp_path):
    rng = np.random.default_rng(1)
    truth = performer(rig, ibug, rng)
    calibration = calibrate_performer(rig, ibug, truth.positions(rig), units="cm")
    path = save_marker_set(calibration.markers, rig, tmp_path / "actor.markers.json", note="take 1")
    loaded = load_marker_set(path, rig)
    assert loaded.placed and loaded.layout == "ibug68" and loaded.names == ibug.names
    np.testing.assert_allclose(loaded.positions(rig), calibration.markers.positions(rig), atol=1e-5)
    np.testing.assert_array_equal(loaded.sliding, ibug.sliding)
    np.testing.assert_allclose(loaded.tangents, calibration.markers.tangents, atol=1e-4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = calibrate_performer(rig, loaded, truth.positions(rig), units="cm", place=False)
    assert again.markers is loaded
