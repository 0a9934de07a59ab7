"""Tests for mimetic.speech.timings: timing files in and out, and naive timing from text."""

from __future__ import annotations

import json
import math

import pytest
from praatio import textgrid

from mimetic.errors import SpeechError
from mimetic.speech import nso, timings
from mimetic.speech.english import ARPABET_VOWELS, text_to_phonemes
from mimetic.speech.phones import SILENCE, Phone, PhoneTimings
from mimetic.speech.timings import (
    PAUSE_S,
    SENTENCE_PAUSE_S,
    english_duration_s,
    load_timings,
    naive_timings,
    parse_label,
    save_timings,
    timings_from_words,
)
from mimetic.testing import require_shared_data

LIBRIVOX = "speech/librivox/sense_and_sensibility_01_austen_64kb-"
UTTERANCES = ("0870", "0880", "0890", "0920", "0930")
BOBBY_LABELS = ["SIL", "B", "AA", "B", "IY", "R", "IH", "P", "T", "DH", "AH", "L", "EH", "JH", "ER", "SIL"]


def sample() -> PhoneTimings:
    """'Hello, world' with stress, words and a pause, starting at 0 without gaps."""
    return naive_timings("Hello, world")


def write_textgrid(path, tiers, end):
    grid = textgrid.Textgrid()
    for name, entries in tiers.items():
        grid.addTier(textgrid.IntervalTier(name, entries, 0, end))
    grid.save(str(path), format="long_textgrid", includeBlankSpaces=True)
    return path


# --------------------------------------------------------------------------- labels


@pytest.mark.parametrize(
    ("raw", "language", "expected"),
    [
        ("AA1", "en", [("AA", 1)]),
        ("", "en", [(SILENCE, None)]),
        ("sp", "en", [(SILENCE, None)]),
        ("<sil>", "en", [(SILENCE, None)]),
        ("+NSN+", "en", [(SILENCE, None)]),
        ("PT", "en", [("P", None), ("T", None)]),
        ("P T", "en", [("P", None), ("T", None)]),
        ("AA1B", "en", [("AA", 1), ("B", None)]),
        ("kg", "nso", [("KG", None)]),
        ("KGO", "nso", [("KG", None), ("O", None)]),
    ],
)
def test_parse_label_reads_pauses_stress_and_merged_phones(raw, language, expected):
    assert parse_label(raw, language) == expected


@pytest.mark.parametrize(("raw", "language"), [("QX", "en"), ("AX", "en"), ("Q", "nso"), ("AA1", "nso")])
def test_parse_label_unknown_raises_with_suggestion_list(raw, language):
    with pytest.raises(SpeechError, match="valid phones"):
        parse_label(raw, language)


# --------------------------------------------------------------------------- TextGrid


def test_load_bobby_textgrid_handles_late_start_merged_label_and_stress():
    timings = load_timings(require_shared_data("speech/praatio/bobby_phones.TextGrid"))
    assert [p.label for p in timings.phones] == BOBBY_LABELS
    assert timings.phones[0].start_s == pytest.approx(0.0124716553288)  # the tier starts after 0
    p, t = timings.phones[7:9]
    assert p.start_s == pytest.approx(0.521315192744) and t.end_s == pytest.approx(0.658052967538796)
    assert p.end_s == t.start_s and p.duration_s == pytest.approx(t.duration_s)  # "PT" split evenly
    assert [p.stress for p in timings.phones[1:5]] == [None, 1, None, 0]
    assert timings.words == () and all(p.word is None for p in timings.phones)


def test_load_bobby_words_textgrid_has_no_phone_tier():
    with pytest.raises(SpeechError, match=r"no phone tier among the interval tiers \['word', 'phrase'\]"):
        load_timings(require_shared_data("speech/praatio/bobby_words.TextGrid"))


def test_load_textgrid_short_format_equals_long(tmp_path):
    source = require_shared_data("speech/praatio/bobby_phones.TextGrid")
    grid = textgrid.openTextgrid(str(source), includeEmptyIntervals=True)
    grid.save(str(tmp_path / "short.TextGrid"), format="short_textgrid", includeBlankSpaces=True)
    assert "intervals [" not in (tmp_path / "short.TextGrid").read_text()
    short, long = load_timings(tmp_path / "short.TextGrid"), load_timings(source)
    assert [p.label for p in short.phones] == [p.label for p in long.phones]
    assert [p.end_s for p in short.phones] == pytest.approx([p.end_s for p in long.phones])


def test_load_mfa_textgrid_fills_words_and_pauses(tmp_path):
    words = [(0.1, 0.4, "hello"), (0.5, 0.9, "world")]
    phones = [(0.1, 0.2, "HH"), (0.2, 0.25, "AH0"), (0.25, 0.3, "L"), (0.3, 0.4, "OW1"), (0.4, 0.5, "sp")]
    phones += [(0.5, 0.6, "W"), (0.6, 0.7, "ER1"), (0.7, 0.8, "L"), (0.8, 0.9, "D"), (0.9, 1.0, "sil")]
    path = write_textgrid(tmp_path / "mfa.TextGrid", {"words": words, "phones": phones}, 1.0)
    result = load_timings(path)
    assert result.words == ("hello", "world")
    assert [p.label for p in result.phones] == [
        "SIL",
        "HH",
        "AH",
        "L",
        "OW",
        "SIL",
        "W",
        "ER",
        "L",
        "D",
        "SIL",
    ]
    assert [p.word for p in result.phones] == [None, 0, 0, 0, 0, None, 1, 1, 1, 1, None]
    assert result.phones[5].start_s == pytest.approx(0.4) and result.phones[5].end_s == pytest.approx(0.5)
    assert result.end_s == pytest.approx(1.0)


def test_load_textgrid_unknown_merged_label_names_interval(tmp_path):
    path = write_textgrid(tmp_path / "bad.TextGrid", {"phone": [(0.0, 0.1, "B"), (0.1, 0.2, "QX")]}, 0.2)
    with pytest.raises(
        SpeechError, match=r"bad.TextGrid: tier 'phone' interval 2: unknown ARPAbet phone 'QX'"
    ):
        load_timings(path)


@pytest.mark.parametrize(
    "content",
    ["hello world\n", 'File type = "ooTextFile"\nObject class = "TextGrid"\n\nxmin = 0\nxmax = ', ""],
)
def test_load_corrupt_textgrid_raises_speech_error(tmp_path, content):
    path = tmp_path / "corrupt.TextGrid"
    path.write_text(content)
    with pytest.raises(SpeechError, match=r"corrupt\.TextGrid: not a readable Praat TextGrid"):
        load_timings(path)


def test_load_textgrid_with_inverted_interval_raises(tmp_path):
    text = require_shared_data("speech/praatio/bobby_phones.TextGrid").read_text()
    path = tmp_path / "inverted.TextGrid"
    path.write_text(text.replace("xmax = 0.08438971390281873", "xmax = 0.01", 1))
    with pytest.raises(SpeechError, match=r"inverted.TextGrid: .*0.01"):
        load_timings(path)


# --------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("suffix", [".TextGrid", ".csv", ".json"])
def test_save_then_load_returns_equal_timings(tmp_path, suffix):
    original = sample()
    assert original.words == ("hello", "world") and any(p.stress == 1 for p in original.phones)
    path = save_timings(original, tmp_path / f"hello{suffix}")
    assert load_timings(path) == original


@pytest.mark.parametrize("suffix", [".TextGrid", ".csv", ".json"])
def test_save_then_load_northern_sotho(tmp_path, suffix):
    original = naive_timings("Ke a leboga, tšhwene.", language="nso")
    path = save_timings(original, tmp_path / f"nso{suffix}")
    assert load_timings(path, language="nso") == original


def test_save_textgrid_gap_reads_back_as_pause(tmp_path):
    gapped = PhoneTimings((Phone("B", 0.0, 0.1, None, 0), Phone("AA", 0.2, 0.3, 1, 0)), words=("ba",))
    result = load_timings(save_timings(gapped, tmp_path / "gap.TextGrid"))
    assert [(p.label, p.start_s, p.end_s) for p in result.phones] == [
        ("B", 0.0, 0.1),
        (SILENCE, 0.1, 0.2),
        ("AA", 0.2, 0.3),
    ]
    assert result.words == ("ba",)


def test_save_unknown_suffix_raises(tmp_path):
    with pytest.raises(SpeechError, match=r"cannot write timings as \.txt; use \.TextGrid, \.csv, \.json"):
        save_timings(sample(), tmp_path / "out.txt")
    assert not (tmp_path / "out.txt").exists()


def test_failed_csv_save_leaves_existing_file_untouched(tmp_path, monkeypatch):
    path = save_timings(sample(), tmp_path / "good.csv")
    before = path.read_bytes()
    calls = []

    def failing_label(phone):
        calls.append(phone)
        if len(calls) == 3:
            raise RuntimeError("disk on fire")
        return phone.label

    monkeypatch.setattr(timings, "_label", failing_label)
    with pytest.raises(RuntimeError, match="disk on fire"):
        save_timings(naive_timings("a much longer sentence"), path)
    assert len(calls) == 3  # it failed midway through the rows
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv"]


def test_failed_textgrid_save_leaves_existing_file_untouched(tmp_path, monkeypatch):
    path = save_timings(sample(), tmp_path / "good.TextGrid")
    before = path.read_bytes()

    def half_save(self, fn, **kwargs):
        with open(fn, "w") as handle:
            handle.write('File type = "ooTextFile"\n')
        raise OSError("no space left on device")

    monkeypatch.setattr(textgrid.Textgrid, "save", half_save)
    with pytest.raises(OSError, match="no space left"):
        save_timings(naive_timings("another sentence"), path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.TextGrid"]


# --------------------------------------------------------------------------- CSV and JSON as users write them


def test_load_csv_user_file_with_word_column(tmp_path):
    path = tmp_path / "user.csv"
    path.write_text("Phoneme, Start, End, Word\nsil,0,0.1,\nHH,0.1,0.2,hi\nAY1,0.2,0.35,hi\nHH,0.35,0.4,hi\n")
    path.write_text(path.read_text() + "AY1,0.4,0.5,hi\n")
    result = load_timings(path)
    assert [p.label for p in result.phones] == ["SIL", "HH", "AY", "HH", "AY"]
    assert result.phones[2].stress == 1
    assert result.words == ("hi",)  # consecutive phones of the same word text make one word


def test_load_json_bare_list_and_language_from_file(tmp_path):
    bare = tmp_path / "bare.json"
    bare.write_text(
        json.dumps([{"phoneme": "M", "start": 0, "end": 0.1}, {"phoneme": "AA1", "start": 0.1, "end": 0.3}])
    )
    result = load_timings(bare)
    assert [(p.label, p.stress) for p in result.phones] == [
        ("M", None),
        ("AA", 1),
    ] and result.language == "en"
    tagged = tmp_path / "tagged.json"
    tagged.write_text(json.dumps({"language": "nso", "phones": [{"phoneme": "KG", "start": 0, "end": 0.1}]}))
    assert load_timings(tagged).language == "nso"


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("a.csv", "phoneme,start,end\nAA,0,0.1\nB,0.1,soon\n", r"a.csv: line 3: 'soon' is not a time"),
        ("b.csv", "label,begin,stop\nAA,0,0.1\n", r"b.csv: line 1 must be the header 'phoneme,start,end'"),
        ("c.csv", "phoneme,start,end\nAA,0,0.1\nAX,0.1,0.2\n", r"c.csv: line 3: unknown ARPAbet phone 'AX'"),
        ("d.csv", "phoneme,start,end\nAA,0,0.1\nB,0.2\n", r"d.csv: line 3 has 2 fields, the header 3"),
        ("e.csv", "phoneme,start,end\nAA,0,0.2\nB,0.1,0.3\n", r"e.csv: phones overlap"),
        ("f.csv", "phoneme,start,end\nAA,0.2,0.1\n", r"f.csv: line 2: .*must end after it starts"),
        ("g.csv", "phoneme,start,end\nAA,0,nan\n", r"g.csv: line 2: time 'nan' is not finite"),
        ("a.json", '{"phones": [\n{"phoneme": "AA", "start": 0,}\n]}', r"a.json: not valid JSON: .* line 2"),
        (
            "b.json",
            '[{"phoneme": "AA", "start": 0, "end": 0.1}, {"phoneme": "B"}]',
            r"b.json: phones\[1\] must",
        ),
        (
            "c.json",
            '{"words": [], "phones": [{"phoneme": "AA", "start": 0, "end": 1, "word": 3}]}',
            r"'word' 3",
        ),
        ("d.json", '{"something": 1}', r"d.json: expected a list"),
        ("e.json", '{"language": "xx", "phones": []}', r"unknown language 'xx'"),
        ("f.txt", "just some words\n", r"f.txt: unknown timing format"),
    ],
)
def test_load_corrupt_csv_json_names_the_problem(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(SpeechError, match=message):
        load_timings(path)


def test_load_missing_file_and_unknown_language(tmp_path):
    with pytest.raises(SpeechError, match="no such timing file"):
        load_timings(tmp_path / "missing.csv")
    with pytest.raises(SpeechError, match="unknown language 'fr'"):
        load_timings(tmp_path / "missing.csv", language="fr")


def test_content_sniffing_reads_csv_and_json_without_their_suffix(tmp_path):
    (tmp_path / "a.dat").write_text("phoneme,start,end\nAA,0,0.1\n")
    (tmp_path / "b.dat").write_text('[{"phoneme": "AA", "start": 0, "end": 0.1}]')
    assert load_timings(tmp_path / "a.dat") == load_timings(tmp_path / "b.dat")


# --------------------------------------------------------------------------- pocketsphinx JSON


@pytest.mark.parametrize("utterance", UTTERANCES)
def test_load_pocketsphinx_phone_json_tiles_the_utterance(utterance):
    path = require_shared_data(f"{LIBRIVOX}{utterance}.phone.json")
    data = json.loads(path.read_text())
    result = load_timings(path)
    transcript = require_shared_data(f"{LIBRIVOX}{utterance}.txt").read_text().split()
    assert list(result.words) == transcript  # "and(2)" → "and", "<sil>" is a pause
    assert result.phones[0].label == SILENCE and result.start_s == 0.0
    expected = sum(len(w["w"]) for w in data["w"])
    assert len(result.phones) == expected
    for before, after in zip(result.phones, result.phones[1:], strict=False):
        assert after.start_s == pytest.approx(before.end_s, abs=1e-9)
    for phone in result.spoken():
        assert result.words[phone.word] in transcript


def test_load_pocketsphinx_word_json_explains_phone_align():
    with pytest.raises(SpeechError, match="word alignment; align with '-phone_align yes'"):
        load_timings(require_shared_data(f"{LIBRIVOX}0880.json"))


def test_timings_from_words_drops_variants_and_fillers():
    result = timings_from_words(
        [
            ("<s>", [("SIL", 0.0, 0.1)]),
            ("to(3)", [("T", 0.1, 0.2), ("UW", 0.2, 0.3)]),
            ("[NOISE]", [("+NSN+", 0.3, 0.4)]),
        ]
    )
    assert result.words == ("to",)
    assert [(p.label, p.word) for p in result.phones] == [
        (SILENCE, None),
        ("T", 0),
        ("UW", 0),
        (SILENCE, None),
    ]


# --------------------------------------------------------------------------- naive timing


def test_naive_timings_are_contiguous_from_zero_with_words():
    result = naive_timings("Bobby ripped the ledger, then left. Twice!")
    assert result.start_s == 0.0
    for before, after in zip(result.phones, result.phones[1:], strict=False):
        assert after.start_s == before.end_s and after.end_s > after.start_s
    assert result.words == ("bobby", "ripped", "the", "ledger", "then", "left", "twice")
    spoken = [
        label for w in text_to_phonemes("Bobby ripped the ledger, then left. Twice!") for label, _ in w.phones
    ]
    assert [p.label for p in result.phones] == spoken


def test_naive_timings_pauses_at_punctuation():
    pauses = [p for p in naive_timings("One, two. Three").phones if p.label == SILENCE]
    assert [p.duration_s for p in pauses] == pytest.approx([PAUSE_S, SENTENCE_PAUSE_S])


@pytest.mark.parametrize("language", ["en", "nso"])
def test_naive_timings_rate_two_halves_every_duration(language):
    text = "the quick brown fox, again" if language == "en" else "ke a leboga, tšhwene"
    normal, fast = naive_timings(text, language=language), naive_timings(text, language=language, rate=2.0)
    assert fast.end_s == pytest.approx(normal.end_s / 2)
    assert [p.duration_s for p in fast.phones] == pytest.approx([p.duration_s / 2 for p in normal.phones])
    assert [p.label for p in fast.phones] == [p.label for p in normal.phones]


def test_naive_timings_northern_sotho_uses_its_duration_table():
    result = naive_timings("kgomo", language="nso")
    assert [p.label for p in result.phones] == ["KG", "O_OPEN", "M", "O_OPEN"]  # unmarked o: open-mid
    assert [p.duration_s for p in result.phones] == pytest.approx(
        [nso.DURATIONS_S[p.label] for p in result.phones]
    )


@pytest.mark.parametrize("rate", [0.0, -1.0, math.inf, math.nan])
def test_naive_timings_rejects_bad_rate(rate):
    with pytest.raises(SpeechError, match="rate must be a positive number"):
        naive_timings("hello", rate=rate)


def test_naive_timings_rejects_empty_text_and_unknown_language():
    with pytest.raises(SpeechError, match="no words to time"):
        naive_timings(" ?! ")
    with pytest.raises(SpeechError, match="unknown language 'de'"):
        naive_timings("hallo", language="de")


def test_english_durations_are_in_typical_ranges():
    vowels = [english_duration_s(v, 1) for v in ARPABET_VOWELS]
    assert 0.09 <= min(vowels) and max(vowels) <= 0.25  # IH 97 ms … OY 228 ms (a diphthong)
    stops = [english_duration_s(c, None) for c in ("P", "T", "K", "B", "D", "G")]
    assert 0.06 <= min(stops) and max(stops) <= 0.08
    assert english_duration_s("AH", 0) < english_duration_s("AH", 1)
    assert all(english_duration_s(v, 0) < english_duration_s(v, 1) for v in ARPABET_VOWELS)


@pytest.mark.parametrize("utterance", UTTERANCES)
def test_naive_timings_length_is_close_to_librivox_speech(utterance):
    reference = load_timings(require_shared_data(f"{LIBRIVOX}{utterance}.phone.json"))
    naive = naive_timings(require_shared_data(f"{LIBRIVOX}{utterance}.txt").read_text())
    ratio = sum(p.duration_s for p in naive.spoken()) / sum(p.duration_s for p in reference.spoken())
    assert 0.8 < ratio < 1.2, f"naive / spoken duration {ratio:.2f}"


def test_boundary_errors_match_phones_in_order_and_measure_both_ends():
    from mimetic.speech.timings import boundary_errors

    reference = PhoneTimings((Phone("B", 0.0, 0.1), Phone("AA", 0.1, 0.3), Phone("B", 0.3, 0.4)))
    shifted = PhoneTimings(
        (Phone("B", 0.02, 0.1), Phone("AH", 0.1, 0.2), Phone("AA", 0.2, 0.32), Phone("B", 0.32, 0.4))
    )
    errors, matched = boundary_errors(shifted, reference)
    assert matched == 3  # the extra AH is skipped
    assert sorted(errors) == pytest.approx(sorted([0.02, 0.0, 0.1, 0.02, 0.02, 0.0]), abs=1e-12)
