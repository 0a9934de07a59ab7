"""Viseme maps: the built-in maps' coverage and shapes (measured on the wire engine's geometry),
the target formula, and the loader's errors."""

from __future__ import annotations

import json
import math
from importlib import resources

import numpy as np
import pytest

from mimetic.animate import mpeg4
from mimetic.errors import SpeechError
from mimetic.speech.phones import SILENCE
from mimetic.speech.visemes import (
    BUILT_IN,
    CLASSES,
    GROUPS,
    channel_group,
    load_viseme_map,
    phone_targets,
    viseme_map,
)

ARPABET = (
    "AA AE AH AO AW AY B CH D DH EH ER EY F G HH IH IY JH K L M N NG OW OY P R S SH T TH UH UW V W Y Z ZH"
).split()


def _landmarks(rig, vertices, names):
    """Positions (k, 3) of rig landmarks on deformed ``vertices`` (n, 3)."""
    points = [rig.landmarks[n] for n in names]
    corners = vertices[rig.mesh.faces[[p.face for p in points]]]  # (k, 3, 3)
    return np.einsum("kj,kjd->kd", np.array([p.bary for p in points]), corners)


def _mouth(rig, engine, values):
    """Lip gap, mouth width, lower lip → upper teeth distance and lip protrusion (rig units)."""
    v = engine.deform(values)
    rest = rig.mesh.vertices
    names = ["upper_lip_inner", "lower_lip_inner", "mouth_corner_L", "mouth_corner_R", "upper_lip_top"]
    upper, lower, left, right, top = _landmarks(rig, v, names)
    teeth = rig.mesh.part_vertices("teeth_upper")
    return {
        "gap": float(np.linalg.norm(upper - lower)),
        "width": float(np.linalg.norm(left - right)),
        "lip_teeth": float(np.linalg.norm(v[teeth] - lower, axis=1).min()),
        "forward": float(top[2] - _landmarks(rig, rest, ["upper_lip_top"])[0, 2]),
    }


# ---- the built-in maps


@pytest.mark.parametrize("name", BUILT_IN)
def test_built_in_map_targets_are_in_range_for_every_phone(rig, name):
    vmap = viseme_map(name)
    labels = list(vmap.phones)
    targets = phone_targets(vmap, labels, rig)
    assert targets.shape == (len(labels), len(rig.channels)) and targets.dtype == np.float64
    lo, hi = np.array([[c.minimum, c.maximum] for c in rig.channels]).T
    assert np.isfinite(targets).all() and (targets >= lo).all() and (targets <= hi).all()
    assert set(vmap.channels) <= set(rig.channel_names)
    silence = targets[labels.index(SILENCE)]
    np.testing.assert_array_equal(silence, [c.default for c in rig.channels])
    assert vmap.phones[SILENCE].kind == "silence"


def test_english_map_covers_arpabet_with_at_least_13_visemes_plus_silence():
    vmap = viseme_map("en")
    assert set(ARPABET) | {SILENCE} == set(vmap.phones)
    assert len(vmap.visemes) >= 14 and vmap.visemes["sil"] == {}
    assert vmap.language == "en" and vmap.description
    assert {vmap.phones[p].kind for p in "P B M".split()} == {"bilabial"}
    assert {vmap.phones[p].kind for p in "F V".split()} == {"labiodental"}


def test_english_map_puts_the_tongue_where_the_consonant_is_made(rig):
    vmap = viseme_map("en")
    t = dict(zip(ARPABET, phone_targets(vmap, ARPABET, rig), strict=True))
    tip, back, out = (rig.channel_names.index(n) for n in ("tongue_tip_up", "tongue_back", "tongue_out"))
    assert all(t[p][tip] >= 0.5 for p in "T D N L".split())
    assert all(t[p][back] >= 0.5 for p in "K G NG".split())
    assert all(t[p][out] > 0.1 for p in "TH DH".split())
    assert all(t[p][out] == 0 for p in ARPABET if p not in ("TH", "DH"))


def test_mpeg4_map_reuses_the_14_mpeg4_visemes_plus_neutral():
    vmap = viseme_map("mpeg4")
    table = mpeg4.visemes()
    assert len(vmap.visemes) == 15 and len(table) == 15
    assert vmap.visemes["neutral"] == {}
    for viseme in table[1:]:
        assert dict(vmap.visemes["_".join(viseme.phonemes)]) == dict(viseme.values)
    assert set(ARPABET) <= set(vmap.phones)
    assert dict(vmap.phones["P"].blend) == {"p_b_m": 1.0} and dict(vmap.phones["AA"].blend) == {"A:": 1.0}


def test_nso_map_covers_every_northern_sotho_phone():
    nso = pytest.importorskip("mimetic.speech.nso")
    vmap = viseme_map("nso")
    assert vmap.language == "nso"
    missing = sorted(set(nso.PHONES) - set(vmap.phones))
    assert missing == []
    assert all(vmap.phones[v].kind in ("vowel", "rounded", "spread") for v in nso.VOWELS)


def test_nso_map_holds_the_surveys_blends(rig):
    vmap = viseme_map("nso")
    assert dict(vmap.phones["D"].blend) == {"CH": 1.0, "Closed": 0.5}
    assert dict(vmap.phones["P"].blend) == {"M": 1.0, "TH": 0.7}
    s = vmap.phones["S"]
    assert dict(s.blend) == {} and s.offsets["tongue_back"] > 0 and s.deformability["lips"] == 1.0
    # D: the teeth nearly clenched (jaw closer than English d), the lips of CH
    nso_d, en_d = phone_targets(vmap, ["D"], rig)[0], phone_targets(viseme_map("en"), ["D"], rig)[0]
    jaw, oo = rig.channel_names.index("jaw_open"), rig.channel_names.index("orbicularis_oris")
    assert nso_d[jaw] < en_d[jaw] and nso_d[oo] > en_d[oo]


def test_vowel_jaw_opening_follows_openness(rig):
    for name in ("en", "mpeg4"):
        jaw = phone_targets(viseme_map(name), ["AA", "EH", "IH", "IY", "UW"], rig)[
            :, rig.channel_names.index("jaw_open")
        ]
        aa, eh, ih, iy, uw = jaw
        assert aa > eh > ih >= iy and uw < eh, name
    nso = phone_targets(viseme_map("nso"), ["A", "E_OPEN", "E", "I", "U"], rig)[
        :, rig.channel_names.index("jaw_open")
    ]
    assert nso[0] > nso[1] > nso[2] > nso[3] and nso[4] < nso[2]
    # open-mid (unmarked e, o) opens the jaw a little more than close-mid (ê, ô): 10-80 % more
    mid = phone_targets(viseme_map("nso"), ["E_OPEN", "E", "O_OPEN", "O"], rig)[
        :, rig.channel_names.index("jaw_open")
    ]
    ratios = (mid[0] / mid[1], mid[2] / mid[3])
    assert all(1.1 < r < 1.8 for r in ratios), ratios


def test_nso_fs_is_bilabial_and_ps_one_target(rig):
    """fs and fš are bilabial [ɸs] [ɸʃ] (the Lwazi phone set): no lower lip on the teeth as for f;
    ps, psh, pšh (one phone each) close the lips."""
    vmap = viseme_map("nso")
    lower = rig.channel_names.index("orbicularis_oris_marginalis_lower")
    f, fs, fsh = phone_targets(vmap, ["F", "FS", "FSH"], rig)[:, lower]
    assert f > 0.5 and fs < 0.2 * f and fsh < 0.2 * f
    assert {vmap.phones[p].kind for p in ("FS", "FSH", "PS", "PS_H", "PSH_H")} == {"bilabial"}


# ---- shapes on the geometry


def test_english_visemes_shape_the_mouth_on_the_geometry(rig, engine):
    vmap = viseme_map("en")
    labels = ["SIL", "P", "B", "M", "AA", "F", "V", "UW", "W", "IY", "S", "EH"]
    shape = {p: _mouth(rig, engine, t) for p, t in zip(labels, phone_targets(vmap, labels, rig), strict=True)}
    rest, scale = shape["SIL"], rig.scale
    assert rest["gap"] < 1e-6 * scale
    for p in "P B M".split():  # lips in contact (measured 0.37 % of head height: pressed, rolled in a little)
        assert shape[p]["gap"] < 0.01 * scale
    assert shape["AA"]["gap"] > 0.1 * scale  # measured 12.7 %
    assert shape["EH"]["gap"] > 0.05 * scale
    for p in "F V".split():  # the lower lip up under the upper incisors (measured 0.44 of rest)
        assert shape[p]["lip_teeth"] < 0.5 * rest["lip_teeth"]
        assert shape[p]["lip_teeth"] < min(s["lip_teeth"] for q, s in shape.items() if q not in "FV")
    for p in "UW W".split():  # rounded: narrower and pushed forward (measured 0.90, +1 cm)
        assert shape[p]["width"] < 0.92 * rest["width"] and shape[p]["forward"] > 0.02 * scale
    for p in "IY S".split():  # spread: wider
        assert shape[p]["width"] > 1.02 * rest["width"]


# ---- the target formula


def test_phone_targets_blend_visemes_add_offsets_then_clip(rig):
    vmap = load_viseme_map(
        {
            "visemes": {"open": {"jaw_open": 0.1}, "wide": {"risorius_L": 0.4}},
            "phones": {
                "X": {"blend": {"open": 1.0, "wide": 0.5}, "offsets": {"tongue_out": 0.2}, "class": "vowel"},
                "Y": {"blend": {"open": 10.0}, "class": "vowel"},
            },
        }
    )
    labels = ["X", "Y", "X"]
    targets = phone_targets(vmap, labels, rig)
    assert labels == ["X", "Y", "X"]
    expected = np.zeros(len(rig.channels))
    expected[[rig.channel_names.index(n) for n in ("jaw_open", "risorius_L", "tongue_out")]] = [0.1, 0.2, 0.2]
    np.testing.assert_allclose(targets[0], expected, atol=1e-15)
    np.testing.assert_array_equal(targets[2], targets[0])
    assert targets[1, rig.channel_names.index("jaw_open")] == rig.channel("jaw_open").maximum


def test_deformability_comes_from_the_class_and_overrides():
    vmap = load_viseme_map(
        {
            "visemes": {"a": {"jaw_open": 0.1}},
            "phones": {
                "P": {"blend": {"a": 1}, "class": "bilabial"},
                "Q": {"blend": {"a": 1}, "class": "bilabial", "deformability": 0.5},
                "R": {"blend": {"a": 1}, "class": "bilabial", "deformability": {"jaw": 0.9}},
            },
        }
    )
    assert dict(vmap.phones["P"].deformability) == dict(CLASSES["bilabial"])
    assert dict(vmap.phones["Q"].deformability) == dict.fromkeys(GROUPS, 0.5)
    assert dict(vmap.phones["R"].deformability) == {**CLASSES["bilabial"], "jaw": 0.9}
    assert vmap.phones[SILENCE].kind == "silence"  # added when the map has none


def test_channel_groups():
    assert [channel_group(n) for n in ("jaw_open", "tongue_back", "mentalis", "risorius_L")] == [
        "jaw",
        "tongue",
        "lips",
        "lips",
    ]


def test_map_based_on_a_built_in_replaces_only_what_it_lists(rig):
    # the survey's speaker rounded his final /a/ "almost into a kiss": O + Closed + TH + W
    kiss = {"base": "nso", "phones": {"A": {"blend": {"O": 1, "Closed": 1, "TH": 1, "W": 1}}}}
    vmap = load_viseme_map(kiss, channels=rig)
    base = viseme_map("nso")
    assert vmap.language == "nso" and vmap.phones["A"].kind == "vowel"
    assert set(vmap.phones) == set(base.phones) and dict(vmap.visemes) == dict(base.visemes)
    a, a_base = phone_targets(vmap, ["A"], rig)[0], phone_targets(base, ["A"], rig)[0]
    oo = rig.channel_names.index("orbicularis_oris")
    assert a[oo] == 1.0 and a_base[oo] == 0.0
    np.testing.assert_array_equal(phone_targets(vmap, ["D", "U"], rig), phone_targets(base, ["D", "U"], rig))


def test_load_viseme_map_reads_a_file_like_the_built_in(rig, tmp_path):
    source = json.loads(resources.files("mimetic.speech").joinpath("data/visemes_en.json").read_text("utf-8"))
    path = tmp_path / "mine.json"
    path.write_text(json.dumps(source))
    vmap = load_viseme_map(path, channels=rig)
    np.testing.assert_array_equal(
        phone_targets(vmap, ARPABET, rig), phone_targets(viseme_map("en"), ARPABET, rig)
    )


# ---- errors


def test_unknown_channel_is_named_with_the_valid_list(rig):
    data = {"visemes": {"a": {"jaw_opne": 0.1}}, "phones": {"X": {"blend": {"a": 1}, "class": "vowel"}}}
    with pytest.raises(SpeechError, match=r"'jaw_opne'.*did you mean jaw_open.*valid channels: .*mentalis"):
        load_viseme_map(data, channels=rig)
    vmap = load_viseme_map(data)  # without a rig it loads, and fails when used
    with pytest.raises(SpeechError, match=r"viseme 'a' sets channel 'jaw_opne'"):
        phone_targets(vmap, ["X"], rig)


def test_unknown_phone_at_use_time_suggests_labels(rig):
    with pytest.raises(SpeechError, match=r"phone 'UWW' is not in viseme map 'en'; did you mean UW"):
        phone_targets(viseme_map("en"), ["AA", "UWW"], rig)
    with pytest.raises(SpeechError, match=r"'AA1'.*did you mean AA"):
        phone_targets(viseme_map("en"), ["AA1"], rig)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"visemes": {"a": {"jaw_open": math.nan}}, "phones": {}}, r"viseme 'a': channel 'jaw_open' = nan"),
        ({"visemes": {"a": {"jaw_open": True}}, "phones": {}}, r"must be a finite number"),
        (
            {"visemes": {"a": {}}, "phones": {"X": {"blend": {"a": math.inf}, "class": "vowel"}}},
            r"phone 'X'.blend: viseme 'a' = inf",
        ),
        (
            {"visemes": {"a": {}}, "phones": {"X": {"blend": {"b": 1}, "class": "vowel"}}},
            r"unknown viseme 'b'",
        ),
        (
            {"visemes": {}, "phones": {"X": {"blend": {}, "class": "plosive"}}},
            r"class 'plosive' must be one of",
        ),
        ({"visemes": {}, "phones": {"X": {"blend": {}}}}, r"class None must be one of"),
        (
            {"visemes": {}, "phones": {"X": {"class": "vowel", "deformability": 1.5}}},
            r"deformability of lips is 1.5",
        ),
        (
            {"visemes": {}, "phones": {"X": {"class": "vowel", "deformability": {"nose": 1}}}},
            r"unknown group",
        ),
        ({"visemes": {}, "phones": {"X": {"class": "vowel", "weight": 1}}}, r"unknown key\(s\) 'weight'"),
        (
            {"visemes": {}, "phones": {"X": {"class": "bilabial", "closure": 0}}},
            r"phone 'X'.closure: 0 must be a number in \(0, 1\]",
        ),
        ({"visemes": {}, "phones": {}, "extra": 1}, r"unknown key\(s\) 'extra'"),
        ({"visemes": {}, "phones": {}}, r"'phones' must be an object"),
        ({"visemes": [], "phones": {"X": {"class": "vowel"}}}, r"'visemes' must be an object"),
        ({"version": 2, "phones": {"X": {"class": "vowel"}}}, r"version 2 is newer"),
        ({"format": "mimetic-arkit", "phones": {}}, r"format 'mimetic-arkit'"),
        ({"base": "fr", "phones": {}}, r"base 'fr' must be one of en, nso, mpeg4"),
        ({"language": "fr", "phones": {"X": {"class": "vowel"}}}, r"language 'fr'"),
    ],
)
def test_load_viseme_map_rejects_bad_maps(data, message):
    with pytest.raises(SpeechError, match=message):
        load_viseme_map(data)


def test_load_viseme_map_rejects_unreadable_files(tmp_path):
    with pytest.raises(SpeechError, match=r"missing.json: no such file"):
        load_viseme_map(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(SpeechError, match=r"bad.json: not valid JSON"):
        load_viseme_map(bad)
    listed = tmp_path / "list.json"
    listed.write_text("[1, 2]")
    with pytest.raises(SpeechError, match=r"list.json: a viseme map is a JSON object"):
        load_viseme_map(listed)
    nan = tmp_path / "nan.json"  # Python's json reads NaN; the map must still refuse it
    nan.write_text(
        '{"visemes": {"a": {"jaw_open": NaN}}, "phones": {"X": {"blend": {"a": 1}, "class": "vowel"}}}'
    )
    with pytest.raises(SpeechError, match=r"nan.json: viseme 'a': channel 'jaw_open' = nan"):
        load_viseme_map(nan)


def test_viseme_map_rejects_unknown_names():
    with pytest.raises(SpeechError, match=r"unknown viseme map 'mpeg'; did you mean 'mpeg4'"):
        viseme_map("mpeg")
