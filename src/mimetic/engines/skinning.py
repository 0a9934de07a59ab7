"""Bones: transforms from the jaw, eyelid, gaze and head channels, and linear blend skinning.

Conventions (right-handed, +Y up, +Z forward; angles in radians, positive as named):

* ``jaw_open`` rotates the jaw about +X through its pivot (the chin moves down and back);
  ``jaw_slide`` and ``jaw_protrude`` translate it along +X and +Z by a fraction of the head height.
* ``eyelid_upper_*`` > 0 closes the upper lid (rotation about +X through the eye centre); its
  maximum is the angle that closes the eye;
  ``eyelid_lower_*`` > 0 raises the lower lid (rotation about -X). The lids and the skin around
  them follow their eye's turn by a soft field (``mimetic.rig.anatomy.gaze``: half the turn at its
  centre, fading over an eye width), and the upper lid's plate follows a further
  ``LID_FOLLOWS_GAZE`` of the pitch, so its margin rides the cornea down about half-way as a real
  lid does. The levator palpebrae and the orbicularis oculi act on the lids through these bones
  (``LID_MUSCLES``), as in the thesis's rig, where the lids are bones.
* ``gaze_yaw`` > 0 turns both eyes to the subject's left (+X), ``gaze_pitch`` > 0 looks up,
  ``gaze_convergence`` turns each eye toward the nose by half its value (< 0: outward),
  ``gaze_vertical_vergence`` turns the left eye up and the right eye down by half its value. So
  each eye turns on its own: left yaw = yaw − convergence / 2, pitch = pitch + vertical / 2;
  right yaw = yaw + convergence / 2, pitch = pitch − vertical / 2 (one eye looking 0.4 rad aside
  or down while the other stays, as ARKit's and ICT's one-eye ``eyeLook`` shapes do).
* ``head_yaw`` > 0 turns the face to the subject's left, ``head_pitch`` > 0 nods the chin down,
  ``head_roll`` > 0 tilts the top of the head to the subject's left; about the head joint.

Every bone except ``head`` is a child of ``head``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mimetic.rig.model import Rig

IDENTITY = np.eye(4)
IDENTITY.setflags(write=False)
LID_FOLLOWS_GAZE = (0.15, 0.0)
"""Upper, lower lid plate rotation per radian of gaze pitch, on top of the soft field (which turns the
margins about 0.35 rad per rad): with it the margins move as much as the plates' (0.5, 0.2) alone did
before the field, looked at in up- and down-gaze on ICT."""
# muscles that move the lids through the lid bones: (upper, lower) closing rotation per unit
# activation, as a fraction of the upper lid's full closing angle (the eyelid_upper channel's maximum)
LID_MUSCLES = {
    "levator_palpebrae": (-0.45, 0.0),  # lifts the upper lid
    "orbicularis_oculi": (1.0, 0.0),  # the sphincter closes the eye (the lower lid meets it)
    "orbicularis_oculi_outer": (0.15, 0.25),  # squint
}


def rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def about(rotation: np.ndarray, pivot: np.ndarray, translation: np.ndarray | None = None) -> np.ndarray:
    """4x4 transform rotating about ``pivot`` (3,), then translating: x -> R (x - p) + p + t."""
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = pivot - rotation @ pivot + (0.0 if translation is None else translation)
    return m


def bone_transforms(rig: Rig, values: np.ndarray) -> np.ndarray:
    """World transforms (b, 4, 4) of the rig's bones, relative to rest, for a pose (c,).

    Channels a rig lacks count as 0. ``transforms[k] @ [x, 1]`` moves a rest point bound to
    bone ``rig.bone_names[k]``.
    """
    named = dict(zip(rig.channel_names, np.asarray(values, dtype=np.float64).tolist(), strict=False))

    def ch(name: str) -> float:
        return named.get(name, 0.0)

    local = {}
    head = rig.bone("head").head
    local["head"] = about(
        rotation_y(ch("head_yaw")) @ rotation_x(ch("head_pitch")) @ rotation_z(-ch("head_roll")), head
    )
    jaw = rig.bone("jaw").head
    shift = rig.scale * np.array([ch("jaw_slide"), 0.0, ch("jaw_protrude")])
    local["jaw"] = about(rotation_x(ch("jaw_open")), jaw, shift)
    for side, sign in (("L", -1.0), ("R", 1.0)):
        centre = rig.bone(f"eye_{side}").head
        pitch = ch("gaze_pitch") - sign * 0.5 * ch("gaze_vertical_vergence")
        upper = ch(f"eyelid_upper_{side}") - LID_FOLLOWS_GAZE[0] * pitch
        lower = ch(f"eyelid_lower_{side}") + LID_FOLLOWS_GAZE[1] * pitch
        closing = rig.channel(f"eyelid_upper_{side}").maximum if f"eyelid_upper_{side}" in named else 0.6
        for muscle, (up, low) in LID_MUSCLES.items():
            upper += up * closing * ch(f"{muscle}_{side}")
            lower += low * closing * ch(f"{muscle}_{side}")
        yaw = ch("gaze_yaw") + sign * 0.5 * ch("gaze_convergence")
        local[f"eyelid_upper_{side}"] = about(rotation_x(upper), rig.bone(f"eyelid_upper_{side}").head)
        local[f"eyelid_lower_{side}"] = about(rotation_x(-lower), rig.bone(f"eyelid_lower_{side}").head)
        local[f"eye_{side}"] = about(rotation_y(yaw) @ rotation_x(-pitch), centre)
    out = np.empty((len(rig.bones), 4, 4))
    for k, bone in enumerate(rig.bones):
        m = local.get(bone.name, IDENTITY)
        out[k] = m if bone.parent is None else local.get(bone.parent, IDENTITY) @ m
    return out


def linear_blend_skinning(vertices: np.ndarray, weights: sp.spmatrix, transforms: np.ndarray) -> np.ndarray:
    """Skinned positions (n, 3): v' = Σ_b w_vb (R_b v + t_b) for weights (n, b) and transforms (b, 4, 4).

    Since each row of weights sums to 1, this is v + Σ_b w_vb (M_b v - v): bones whose transform is
    the identity cost nothing. Pass the weights as CSC (``weights.tocsc()``) to avoid a conversion.
    """
    csc = weights if sp.issparse(weights) and weights.format == "csc" else sp.csc_matrix(weights)
    out = vertices.copy()
    for b in range(transforms.shape[0]):
        m = transforms[b]
        if np.array_equal(m, IDENTITY):
            continue
        rows = csc.indices[csc.indptr[b] : csc.indptr[b + 1]]
        w = csc.data[csc.indptr[b] : csc.indptr[b + 1]][:, None]  # (k, 1)
        p = vertices[rows]
        out[rows] += w * (p @ m[:3, :3].T + m[:3, 3] - p)
    return out


def aim_gaze(rig: Rig, target: np.ndarray) -> dict[str, float]:
    """Gaze channels (yaw, pitch, convergence, vertical vergence; rad) that aim both eyes at
    ``target`` (3,), rig units.

    Each eye looks along +Z at rest; the aim of an eye at centre c is the direction target - c.
    Yaw and pitch are the means of the two eyes', convergence the right eye's yaw minus the left's
    (positive when both turn toward the nose), the vertical vergence the left eye's pitch minus the
    right's (not 0 when the eyes sit at different heights), as ``bone_transforms`` reads them.
    """
    target = np.asarray(target, dtype=np.float64)
    yaws, pitches = [], []
    for side in ("L", "R"):
        d = target - rig.bone(f"eye_{side}").head
        yaws.append(np.arctan2(d[0], d[2]))
        pitches.append(np.arctan2(d[1], np.hypot(d[0], d[2])))
    return {
        "gaze_yaw": float(0.5 * (yaws[0] + yaws[1])),
        "gaze_pitch": float(0.5 * (pitches[0] + pitches[1])),
        "gaze_convergence": float(yaws[1] - yaws[0]),
        "gaze_vertical_vergence": float(pitches[0] - pitches[1]),
    }
