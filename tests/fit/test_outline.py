"""The sliding face outline (``fit.conform``): iBUG's 17 contour points constrain only their
distance across the reference's outline, and the landmark gate (``fit.report``) judges them so.

Real 68-point sets come from the shared data: ICT-FaceKit's own ``landmarks_68`` vertices,
OpenFace's 3D landmarks of a real face video, and MediaPipe's canonical mesh through the
468 → 68 correspondence of PeizhiYan/Mediapipe_2_Dlib_Landmarks (a point given as two MediaPipe
indices is their mean). The end-to-end rigs (ICT and its identity heads, a generated head with an
iBUG-like outline, wrong points) are in test_rig_head.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.fit.conform import (
    OUTLINE,
    eye_distance,
    fit_conformation,
    landmark_model,
    outline_feet,
    sliding_landmarks,
)
from mimetic.fit.report import MAX_LANDMARK_PCT, MAX_LANDMARK_RMS_PCT, NAMED_LANDMARK_PCT
from mimetic.head.landmarks import IBUG68
from mimetic.testing import load_ict, require_shared_data

INNER_MOUTH_CORNERS = (60, 64)  # 0-based iBUG 61 and 65: the same project names as 49 and 55
MEDIAPIPE_68 = (
    (127,), (234,), (93,), (132, 58), (58, 172), (136,), (150,), (176,), (152,), (400,), (379,), (365,),
    (397, 288), (361,), (323,), (454,), (356,),
    (70,), (63,), (105,), (66,), (107,), (336,), (296,), (334,), (293,), (300,),
    (168, 6), (197, 195), (5,), (4,), (75,), (97,), (2,), (326,), (305,),
    (33,), (160,), (158,), (133,), (153,), (144,), (362,), (385,), (387,), (263,), (373,), (380,),
    (61,), (39,), (37,), (0,), (267,), (269,), (291,), (321,), (314,), (17,), (84,), (91,),
    (78,), (82,), (13,), (312,), (308,), (317,), (14,), (87,),
)  # fmt: skip


def ibug_names_points(points68: np.ndarray) -> tuple[list[str], np.ndarray]:
    """Project names and points (66, 3) of a 68-point iBUG set, without the inner mouth corners."""
    keep = [i for i in range(68) if i not in INNER_MOUTH_CORNERS]
    return [IBUG68[i] for i in keep], np.asarray(points68, dtype=np.float64)[keep]


def pct_of_eye_distance(conformation) -> np.ndarray:
    """The conformation's residuals (k,) in % of the fitted model's eye distance."""
    model = landmark_model()
    params = np.array(list(conformation.params.as_dict().values()))
    return 100 * conformation.residual / eye_distance(model, model.positions(params))


@pytest.fixture(scope="module")
def ict68() -> tuple[list[str], np.ndarray]:
    mesh, meta = load_ict(require_shared_data("ict-facekit"))
    return ibug_names_points(mesh.vertices[meta["landmarks_68"]["vertex_indices"]])


def _outline_direction(names: list[str], points: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The file's own outline at ``name``, in its frontal plane: unit tangent and outward normal (3,)."""
    k = OUTLINE.index(name)
    tangent = points[names.index(OUTLINE[k + 1])] - points[names.index(OUTLINE[k - 1])]
    tangent[2] = 0.0
    tangent /= np.linalg.norm(tangent)
    return tangent, np.array([tangent[1], -tangent[0], 0.0])


# ------------------------------------------------------------------------- geometry


def test_outline_feet_measures_only_across_the_outline() -> None:
    model = landmark_model()
    outline = model.base[[model.names.index(n) for n in OUTLINE]]  # (17, 3)
    mid = 0.5 * (outline[:-1] + outline[1:])  # (16, 3) a point inside each segment
    along = np.diff(outline[:, :2], axis=0)
    normal = np.column_stack([along[:, 1], -along[:, 0]]) / np.linalg.norm(along, axis=1, keepdims=True)
    shift = np.linspace(-1.0, 1.0, len(mid))  # cm, across the outline
    points = mid + np.column_stack([shift[:, None] * normal, np.full(len(mid), 7.0)])  # and 7 cm in z
    before = points.copy()
    feet = outline_feet(outline, points)
    assert (
        feet.distance.shape == (16,) and feet.normal.shape == (16, 3) and feet.coefficients.shape == (16, 17)
    )
    assert feet.distance.dtype == np.float64
    np.testing.assert_array_equal(points, before)
    np.testing.assert_allclose(feet.distance, shift, atol=1e-9)  # depth does not count, the side does
    np.testing.assert_allclose(feet.normal[:, :2], normal, atol=1e-9)
    np.testing.assert_allclose((feet.coefficients @ outline)[:, :2], mid[:, :2], atol=1e-9)
    np.testing.assert_allclose(feet.coefficients.sum(axis=1), 1.0, atol=1e-12)  # affine combinations
    # outward: the chin's outline normal points down, the left jaw's to +x
    chin = OUTLINE.index("menton")
    assert feet.normal[chin, 1] < -0.9 and feet.normal[-3, 0] > 0.5


def test_outline_feet_continue_past_the_ends_towards_the_temples() -> None:
    """iBUG 1 and 17 sit at eye level, above the generated head's jaw_R1 / jaw_L1."""
    model = landmark_model()
    outline = model.base[[model.names.index(n) for n in OUTLINE]]
    top = outline[-1] + 2.0 * (outline[-1] - outline[-2]) / np.linalg.norm(outline[-1] - outline[-2])
    feet = outline_feet(outline, top[None])
    assert abs(feet.distance[0]) < 1e-9  # 2 cm beyond jaw_L1, still on the (continued) outline


def test_sliding_landmarks_menton_slides_only_with_the_jaw() -> None:
    names = ["nose_tip", "menton", "jaw_L3", "gonion_L", "zygion_R"]
    np.testing.assert_array_equal(sliding_landmarks(names), [False, True, True, False, False])
    np.testing.assert_array_equal(sliding_landmarks(["nose_tip", "menton"]), [False, False])
    assert sliding_landmarks(list(IBUG68)).sum() == 17


# ------------------------------------------------------------------------- real 68-point sets


def test_fit_conformation_ict68_fits_like_its_49_inner_points(ict68) -> None:
    """All 68 of ICT's points (the outline included) give the conformation and pose of its 49
    inner points, and every landmark fits within the gate."""
    names, points = ict68
    before = points.copy()
    full = fit_conformation(names, points)
    inner = [i for i, n in enumerate(names) if n not in OUTLINE]
    alone = fit_conformation([names[i] for i in inner], points[inner])
    np.testing.assert_array_equal(points, before)
    assert full.residual.shape == (66,) and full.sliding.sum() == 17 and full.weights.shape == (66,)
    pct = pct_of_eye_distance(full)
    assert np.sqrt(np.mean(pct**2)) < 0.5 * MAX_LANDMARK_RMS_PCT  # measured 5.9 % (18.6 % before they slid)
    assert pct.max() < NAMED_LANDMARK_PCT  # measured 13.5 % (nasion)
    assert np.all(pct[full.sliding] < 10.0)  # measured at most 8.1 %
    # the outline lies inside the reference's silhouette: ICT's points sit on the cheek
    assert (
        -0.25 < full.outline_offset / eye_distance(landmark_model(), landmark_model().base) < -0.05
    )  # -0.15
    moved = np.linalg.norm(full.to_model.apply(points) - alone.to_model.apply(points), axis=1)
    assert moved.mean() < 0.06  # cm in the reference frame; measured 0.03
    a = np.array(list(full.params.as_dict().values()))
    b = np.array(list(alone.params.as_dict().values()))
    assert np.abs(a - b).max() < 0.02  # measured 0.009


@pytest.mark.parametrize("frame", [0, 50, 99])
def test_fit_conformation_openface_68_points_fit_a_head(frame: int) -> None:
    """OpenFace's 3D landmarks (mm, camera frame: +Y down, +Z away) of a real face."""
    path = require_shared_data("landmarks/OpenFace_Test.csv")
    data = np.genfromtxt(path, delimiter=",", names=True, autostrip=True)
    xyz = np.array([[data[f"X_{k}"][frame], data[f"Y_{k}"][frame], data[f"Z_{k}"][frame]] for k in range(68)])
    names, points = ibug_names_points(xyz)
    result = fit_conformation(names, points)
    pct = pct_of_eye_distance(result)
    assert result.to_model.scale == pytest.approx(0.1, rel=0.2)  # mm → the reference's cm
    assert np.sqrt(np.mean(pct**2)) < 8.0  # measured 6.2 %
    assert pct.max() < 0.6 * MAX_LANDMARK_PCT  # measured 12 %


@pytest.mark.parametrize(
    "file", ["canonical.npz", "fixtures/portrait_expected_face_geometry.npz"], ids=["canonical", "portrait"]
)
def test_fit_conformation_mediapipe_68_points_fit_a_head(file: str) -> None:
    data = np.load(require_shared_data("mediapipe") / file)
    vertices = data["vertices"].astype(np.float64)
    names, points = ibug_names_points([vertices[list(ids)].mean(axis=0) for ids in MEDIAPIPE_68])
    pct = pct_of_eye_distance(fit_conformation(names, points))
    assert np.sqrt(np.mean(pct**2)) < 0.6 * MAX_LANDMARK_RMS_PCT  # measured 6.1 and 8.2 %
    assert pct.max() < 0.7 * MAX_LANDMARK_PCT  # measured 12 and 18 %


# ------------------------------------------------------------------------- sliding


@pytest.mark.parametrize("name", ["jaw_L4", "menton", "jaw_R2"])
def test_fit_conformation_outline_point_slides_along_but_not_across(ict68, name: str) -> None:
    """4 cm along ICT's outline changes the fit little; 4 cm across it (out of the face) is caught."""
    names, points = ict68
    k = names.index(name)
    tangent, normal = _outline_direction(names, points, name)
    base = fit_conformation(names, points)
    along, across = points.copy(), points.copy()
    along[k] += 4.0 * tangent
    across[k] += 4.0 * normal
    slid = fit_conformation(names, along)
    pushed = fit_conformation(names, across)
    moved = np.linalg.norm(slid.to_model.apply(points) - base.to_model.apply(points), axis=1)
    assert moved.mean() < 0.02  # cm; measured at most 0.003
    a = np.array(list(slid.params.as_dict().values()))
    b = np.array(list(base.params.as_dict().values()))
    assert np.abs(a - b).max() < 0.01
    assert pct_of_eye_distance(slid)[k] < 12.0  # measured 2-6 %
    assert pct_of_eye_distance(pushed)[k] > MAX_LANDMARK_PCT  # measured 44-46 %
    # the pushed point is down-weighted, so it barely moves the others either
    moved = np.linalg.norm(pushed.to_model.apply(points) - base.to_model.apply(points), axis=1)
    assert moved.mean() < 0.05


def test_fit_conformation_with_an_outline_is_invariant_to_a_similarity_of_the_input(ict68) -> None:
    """The outline is measured in the reference frame, so turning, moving and scaling the file
    (here to mm, looking down -X) changes the pose, not the fit."""
    from scipy.spatial.transform import Rotation

    names, points = ict68
    turn = Rotation.from_euler("xyz", [20, -90, 35], degrees=True).as_matrix()
    moved = 10.0 * points @ turn.T + np.array([100.0, -40.0, 600.0])
    a, b = fit_conformation(names, points), fit_conformation(names, moved)
    np.testing.assert_allclose(a.residual, b.residual, atol=1e-6)
    np.testing.assert_allclose(a.outline_offset, b.outline_offset, atol=1e-6)
    np.testing.assert_allclose(
        list(a.params.as_dict().values()), list(b.params.as_dict().values()), atol=1e-6
    )
    np.testing.assert_allclose(b.to_model.apply(moved), a.to_model.apply(points), atol=1e-6)
