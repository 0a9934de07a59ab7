"""Benchmark the lip-sync stage (``mimetic.speech``): alignment accuracy, coarticulation quality, speed.

    python benchmarks/bench_speech.py [--quick]

Three tables, after the load average at the start (the machine is shared; times move with it):

1. Alignment accuracy (needs the shared data's ``speech/`` and pocketsphinx, extra ``[speech]``;
   without either it is skipped with a note). ``align_audio`` on the 5 LibriVox utterances
   (16 kHz) and on praatIO's "bobby" (48 kHz, resampled by ``align_audio``; transcript "bobby
   ripped the ledger"), against the reference phones, measured as ``tests/speech/test_align.py``
   does: the spoken phones of the result and of the reference are matched in order (``difflib`` on
   their labels) and each matched phone's start and end are compared. Columns: phones matched (of
   the reference's spoken phones), median |boundary error|, share of boundaries within 25 and
   50 ms, the largest error, alignment time (median over the rounds, one untimed call first; each
   call builds its decoder, as a user's does) and real-time factor (alignment time / audio
   length). Goals: median ≤ 25 ms and ≥ 90 % within 50 ms, met or NOT met per row.
   **The LibriVox references were themselves made by pocketsphinx** (its ``align`` command with
   the same bundled model, see the shared data's ``speech/PROVENANCE.md``): agreement there shows
   that ``align_audio`` reproduces pocketsphinx, not that pocketsphinx finds the true boundaries.
   **bobby's references are hand labels** (its merged "PT" interval split evenly into P and T by
   ``load_timings``): the independent check. The no-audio baseline: ``naive_timings`` of the
   transcript alone (typical phone durations from 0 s, as ``lip_sync`` times text without audio)
   against the same references, pooled over the LibriVox utterances and for bobby.

1b. Audio alone (same utterances and references as table 1): ``align_audio`` with the transcript;
   ``recognize_timings`` without it, "words" (recognition with the bundled English LM, then forced
   alignment; the default) and "phones" (free phone decoding); a Rhubarb-style baseline (Rhubarb
   Lip Sync's approach: recognised phones mapped to its mouth shapes A-H and X, each held; here the
   "phones" timings mapped by ``RHUBARB``, boundaries measured between shape segments against the
   reference's shape segments); and ``naive_timings`` of the transcript. Columns: phones matched,
   median boundary error, share within 50 ms; lip level: share of 10 ms frames whose Rhubarb shape
   is the reference's, and bilabial closures hit, the reference's P B M whose mid-closure frame has the
   lips closed (mimetic rows: the coarticulated clip's inner lip gap on ``small_rig`` below 0.5 %
   of the head height, as table 2; Rhubarb-style: shape A held there); time per call.

1c. Wrong transcripts: the worst stretch score (``align.stretch_scores``, mean aligned score per
   frame over ≥ 0.5 s) of each LibriVox utterance and bobby with its own transcript, the next
   utterance's text, its words shuffled (seeded) and its second half replaced by the next text's
   start; "no alignment" when pocketsphinx pruned every path (refused anyway). The threshold
   ``align.MISMATCH_SCORE`` must lie above every wrong one and below every correct one. Scored as
   ``align_audio`` scores: on the padded audio, the padded ends' pauses passed over.

2. Coarticulation quality on ``mimetic.testing.small_rig()`` with the wire engine, at 60 fps:
   ``coarticulate`` against the linear baseline ``linear_clip`` (the targets at phone centres
   joined by straight lines), on the same timings: "Bob bought a map by the pub.", "My mom made pea
   soup." and "boot beet" (``naive_timings``), and LibriVox utterance 0870 with its reference
   timings (skipped without the shared data). Per sentence and method, on the frame nearest each
   phone's centre, a bilabial's at its closure's middle (as ``tests/speech/test_coarticulation.py``):
   the inner lip gap (distance between
   the rig's ``upper_lip_inner`` and ``lower_lip_inner`` landmarks on the deformed mesh) at the
   bilabials P B M, largest, in % of the head height (``rig.scale``); the closure hit rate, the
   bilabials whose gap is below the tests' closed threshold (0.5 % of the head height); the
   smallest gap at the open vowels AA AE (the mouth does open); and smoothness, the summed squared
   second difference of the mouth channels (lips and jaw groups) over the clip, with the ratio
   coarticulated / linear (below 1 is smoother). Then, pooled over the sentences: mean
   ``jaw_open`` at the vowels AA, EH, IY (expected order AA > EH > IY) beside the map's targets;
   and ``orbicularis_oris`` (lip rounding) at the centre of /t/ in "boot" and in "beet" (T has no
   lip shape of its own, so any rounding is borrowed from the neighbouring vowel), in the sentence
   (where a B follows boot's T) and in each word timed alone.

3. Speed (``bench_basis.print_table``; cases timed round-robin, median over the rounds): text →
   phones (``naive_timings``) of a 60-word paragraph; ``coarticulate`` of 10 s of speech at 60 fps
   (the paragraph's naive timings, cut at 10 s) against ``linear_clip`` on the same timings in the
   same run; ``lip_sync`` from the paragraph's text, end to end. Times are per 60 fps frame of
   speech produced (a call's time over its clip's frames, the text → phones case over the frames
   its timings would give), so "throughput" is frames of animation per second and 60 frames/s is
   real time. Baselines: ``linear_clip`` for ``coarticulate``, ``lip_sync(..., baseline=True)`` (the
   linear path end to end) for ``lip_sync``. The whole-call times and how many times faster than
   real time each case runs are printed under the table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

import report
from bench_basis import print_table, round_robin, table
from mimetic.engines import make_engine
from mimetic.errors import SpeechError
from mimetic.quality import lip_gap
from mimetic.speech.align import (
    MISMATCH_SCORE,
    PAD_S,
    _align_words,
    _decoder,
    align_audio,
    padded,
    pcm16,
    read_wav,
    stretch_scores,
)
from mimetic.speech.coarticulation import coarticulate, linear_clip
from mimetic.speech.english import text_to_phonemes
from mimetic.speech.lipsync import TAIL_S, lip_sync
from mimetic.speech.phones import SILENCE, Phone, PhoneTimings
from mimetic.speech.recognize import recognize_timings
from mimetic.speech.timings import boundary_errors, load_timings, naive_timings
from mimetic.speech.visemes import channel_group, phone_targets, viseme_map
from mimetic.testing import shared_data_dir, small_rig

TABLES: list[str] = []
"""The tables written to ``out/speech.md`` (``report.save``), in order."""
LIBRIVOX = "speech/librivox/sense_and_sensibility_01_austen_64kb-"
UTTERANCES = ("0870", "0880", "0890", "0920", "0930")
BOBBY = "speech/praatio/bobby"
BOBBY_TRANSCRIPT = "bobby ripped the ledger"
MEDIAN_GOAL_S = 0.025
WITHIN_GOAL_S = 0.05
WITHIN_GOAL = 0.9
NEAR_S = 0.025
FPS = 60.0
BILABIAL = ("P", "B", "M")
OPEN_VOWELS = ("AA", "AE")
JAW_VOWELS = ("AA", "EH", "IY")
CLOSED_GAP_REL = 0.005
"""The tests' closed-lips threshold: inner lip gap below 0.5 % of the head height."""
SENTENCES = ("Bob bought a map by the pub.", "My mom made pea soup.", "boot beet")
CLIP_S = 10.0
PARAGRAPH = (
    "The family of Dashwood had long been settled in Sussex. Their estate was large, and their "
    "residence was at Norland Park, in the centre of their property, where, for many generations, "
    "they had lived in so respectable a manner as to engage the general good opinion of their "
    "surrounding acquaintance. The late owner of this estate was a single man."
)
"""60 words: the opening of *Sense and Sensibility* (1811), the book the LibriVox utterances read."""


def n_frames(timings: PhoneTimings, fps: float = FPS) -> int:
    """Frames of a clip of ``timings`` (``coarticulate``'s count)."""
    return int(np.floor(timings.end_s * fps + 1e-9)) + 1


def closure_frame(phone: Phone, fps: float = FPS) -> int:
    """The frame nearest the middle of a bilabial's closure (``PhoneVisemes.closure``: the start of a
    stop's span, a nasal's whole span), where coarticulation shuts the lips."""
    share = viseme_map("en").phone(phone.label).closure
    return round((phone.start_s + share * phone.duration_s / 2) * fps)


def centre_frame(phone: Phone, fps: float = FPS) -> int:
    """The frame nearest the phone's centre (its dominance peak)."""
    return round((phone.start_s + phone.end_s) / 2 * fps)


# --------------------------------------------------------------------------- 1. alignment accuracy


def accuracy_cells(errors: np.ndarray, matched: int, total: int) -> tuple[list[str], bool]:
    """Cells (matched, median, ≤ 25 ms, ≤ 50 ms, max) and whether both goals are met."""
    median, within = float(np.median(errors)), float(np.mean(errors <= WITHIN_GOAL_S))
    cells = [
        f"{matched}/{total}",
        f"{median * 1e3:.1f}",
        f"{np.mean(errors <= NEAR_S):.1%}",
        f"{within:.1%}",
        f"{errors.max() * 1e3:.0f}",
    ]
    return cells, median <= MEDIAN_GOAL_S and within >= WITHIN_GOAL


def bench_alignment(shared: Path | None, rounds: int) -> None:
    print("\n1. Alignment accuracy: align_audio (pocketsphinx) against reference phones")
    if shared is None:
        print("   shared data speech/ not found (mimetic.testing.shared_data_dir()): table skipped")
        return
    try:
        import pocketsphinx  # noqa: F401
    except ImportError as error:
        print(f"   pocketsphinx not installed (extra [speech]: {error}): table skipped")
        return
    items = []  # (name, reference kind, wav, transcript, reference timings)
    for u in UTTERANCES:
        stem = shared / f"{LIBRIVOX}{u}"
        ref = load_timings(f"{stem}.phone.json")
        items.append((u, "pocketsphinx", Path(f"{stem}.wav"), Path(f"{stem}.txt").read_text().strip(), ref))
    bobby = shared / BOBBY
    items.append(
        (
            "bobby",
            "hand labels",
            Path(f"{bobby}.wav"),
            BOBBY_TRANSCRIPT,
            load_timings(f"{bobby}_phones.TextGrid"),
        )
    )
    align_audio(items[-1][2], items[-1][3])  # untimed: imports pocketsphinx's model and scipy.signal
    header = (
        "utterance",
        "reference",
        "audio s",
        "phones matched",
        "median ms",
        "≤ 25 ms",
        "≤ 50 ms",
        "max ms",
        "time s",
        "RTF",
        "goals",
    )
    # per method ("align", "naive"): name -> (errors, matched, total, seconds, audio_s)
    results: dict[str, dict[str, tuple[np.ndarray, int, int, float, float]]] = {"align": {}, "naive": {}}
    for name, _, wav, transcript, ref in items:
        samples, rate = read_wav(wav)
        seconds = []
        for _ in range(rounds):
            start = time.perf_counter()
            result = align_audio(wav, transcript)
            seconds.append(time.perf_counter() - start)
        start = time.perf_counter()
        naive = naive_timings(transcript)
        naive_s = time.perf_counter() - start
        for method, timings, s in (("align", result, statistics.median(seconds)), ("naive", naive, naive_s)):
            errors, matched = boundary_errors(timings, ref)
            results[method][name] = (errors, matched, len(ref.spoken()), s, len(samples) / rate)
    for method in results:
        librivox = [results[method][u] for u in UTTERANCES]
        results[method]["LibriVox pooled"] = (
            np.concatenate([r[0] for r in librivox]),
            *(sum(r[k] for r in librivox) for k in range(1, 5)),
        )
    kinds = {name: kind for name, kind, *_ in items} | {"LibriVox pooled": "pocketsphinx"}
    rows = []
    for method, names in (
        ("align", [*UTTERANCES, "LibriVox pooled", "bobby"]),
        ("naive", ["LibriVox pooled", "bobby"]),
    ):
        for name in names:
            errors, matched, total, seconds, audio_s = results[method][name]
            cells, met = accuracy_cells(errors, matched, total)
            rows.append(
                (
                    name if method == "align" else f"naive: {name}",
                    kinds[name],
                    f"{audio_s:.2f}",
                    *cells,
                    f"{seconds:.2f}" if method == "align" else f"{seconds:.4f}",
                    f"{seconds / audio_s:.3f}" if method == "align" else f"{seconds / audio_s:.5f}",
                    "met" if met else "NOT met",
                )
            )
    print(
        "   NOTE: the LibriVox references were made by pocketsphinx itself (its align command, same bundled\n"
        "   model): agreement there shows that align_audio reproduces pocketsphinx, not that the boundaries\n"
        "   are right. bobby's references are hand labels (PT split evenly): the independent check.\n"
        f"   goals: median ≤ {MEDIAN_GOAL_S * 1e3:.0f} ms and ≥ {WITHIN_GOAL:.0%} within "
        f"{WITHIN_GOAL_S * 1e3:.0f} ms;\n"
        f"   time = median of {rounds} call(s) after one untimed call; RTF = time / audio.\n"
        "   naive rows: naive_timings of the transcript alone (no audio, from 0 s), the no-audio baseline."
    )
    TABLES.append(table(header, rows, "1. Alignment accuracy"))
    return items


# --------------------------------------------------------------------------- 1b. audio alone

RHUBARB = {
    **dict.fromkeys(("P", "B", "M"), "A"),  # closed lips
    **dict.fromkeys(("EH", "AE", "AH", "EY", "AY", "IH", "IY", "Y"), "C"),  # open
    **dict.fromkeys(("AA", "AW"), "D"),  # wide open
    **dict.fromkeys(("AO", "ER", "OY", "UH"), "E"),  # slightly rounded
    **dict.fromkeys(("UW", "OW", "W", "R"), "F"),  # puckered
    **dict.fromkeys(("F", "V"), "G"),  # upper teeth on the lower lip
    "L": "H",  # tongue raised
    SILENCE: "X",  # idle
}
"""ARPAbet → Rhubarb Lip Sync's mouth shapes (its documented A-H, X); every other consonant is B
(slightly open, teeth together)."""


def shapes(timings: PhoneTimings) -> PhoneTimings:
    """``timings`` as Rhubarb shape segments: each phone's shape, equal neighbours merged."""
    out: list[Phone] = []
    for p in timings.phones:
        label = RHUBARB.get(p.label, "B")
        if out and out[-1].label == label and abs(out[-1].end_s - p.start_s) < 1e-6:
            out[-1] = Phone(label, out[-1].start_s, p.end_s)
        else:
            out.append(Phone(label, p.start_s, p.end_s))
    return PhoneTimings(tuple(p if p.label != "X" else Phone(SILENCE, p.start_s, p.end_s) for p in out))


def shape_frames(timings: PhoneTimings, end_s: float) -> np.ndarray:
    """The Rhubarb shape at each 10 ms frame centre up to ``end_s`` ("X" where no phone is)."""
    t = (np.arange(int(end_s * 100)) + 0.5) / 100
    labels = np.full(len(t), "X", dtype=object)
    for p in timings.phones:
        labels[(t >= p.start_s) & (t < p.end_s)] = RHUBARB.get(p.label, "B")
    return labels


def bench_audio_alone(rig, items: list | None) -> None:
    print("\n1b. Audio alone: recognised timings against the same references")
    if not items:
        print("   table 1 was skipped: skipped too")
        return
    gap, closed = LipGap(rig), CLOSED_GAP_REL * 100
    methods = ("text+audio", "audio: words", "audio: phones", "Rhubarb-style", "naive text")
    acc = {
        m: {"errors": [], "matched": 0, "total": 0, "frames": [0, 0], "bilabial": [0, 0], "s": []}
        for m in methods
    }
    per = {}
    for name, _, wav, transcript, ref in items:
        group = "bobby" if name == "bobby" else "LibriVox"
        samples, rate = read_wav(wav)
        audio_s = len(samples) / rate
        runs = {}
        for method, call, args, kwargs in (
            ("text+audio", align_audio, (wav, transcript), {}),
            ("audio: words", recognize_timings, (wav,), {}),
            ("audio: phones", recognize_timings, (wav,), {"method": "phones"}),
            ("naive text", naive_timings, (transcript,), {}),
        ):
            start = time.perf_counter()
            runs[method] = call(*args, **kwargs)
            acc[method]["s"].append(time.perf_counter() - start)
        runs["Rhubarb-style"] = runs["audio: phones"]
        acc["Rhubarb-style"]["s"].append(acc["audio: phones"]["s"][-1])
        ref_frames = shape_frames(ref, audio_s)
        bilabials = [p for p in ref.spoken() if p.label in BILABIAL]
        for method, timings in runs.items():
            key = (method, group)
            a = per.setdefault(
                key, {"errors": [], "matched": 0, "total": 0, "frames": [0, 0], "bilabial": [0, 0]}
            )
            if method == "Rhubarb-style":
                errors, matched = boundary_errors(shapes(timings), shapes(ref))
                total = len(shapes(ref).spoken())
                hits = sum(
                    shape_frames(timings, audio_s)[
                        min(int((p.start_s + p.end_s) / 2 * 100), len(ref_frames) - 1)
                    ]
                    == "A"
                    for p in bilabials
                )
            else:
                errors, matched = boundary_errors(timings, ref)
                total = len(ref.spoken())
                clip = coarticulate(_with_tail_s(timings), rig, FPS)
                last = clip.n_frames - 1
                hits = sum(gap(clip.values[min(closure_frame(p), last)]) < closed for p in bilabials)
            ours = shape_frames(timings, audio_s)
            for d in (acc[method], a):
                d["errors"].append(errors)
                d["matched"] += matched
                d["total"] += total
                d["frames"][0] += int(np.sum(ours == ref_frames))
                d["frames"][1] += len(ref_frames)
                d["bilabial"][0] += hits
                d["bilabial"][1] += len(bilabials)
    header = (
        "method",
        "utterances",
        "matched",
        "median ms",
        "≤ 50 ms",
        "shape frames",
        "bilabials closed",
        "time s",
    )
    rows = []
    for method in methods:
        for group in ("LibriVox", "bobby"):
            d = per[(method, group)]
            e = np.concatenate(d["errors"])
            rows.append(
                (
                    method if group == "LibriVox" else "",
                    group,
                    f"{d['matched']}/{d['total']}",
                    f"{np.median(e) * 1e3:.1f}",
                    f"{np.mean(e <= WITHIN_GOAL_S):.1%}",
                    f"{d['frames'][0] / d['frames'][1]:.1%}",
                    f"{d['bilabial'][0]}/{d['bilabial'][1]}",
                    f"{statistics.median(acc[method]['s']):.2f}",
                )
            )
    print(
        "   LibriVox: 5 utterances pooled (references by pocketsphinx's aligner); bobby: hand labels.\n"
        "   Rhubarb-style rows compare shape segments (so 'matched' counts shapes, not phones);\n"
        "   shape frames: 10 ms frames whose Rhubarb shape equals the reference's; time: median per call."
    )
    TABLES.append(table(header, rows, "1b. Audio alone"))


def _with_tail_s(timings: PhoneTimings) -> PhoneTimings:
    if timings.phones and timings.phones[-1].label != SILENCE:
        tail = Phone(SILENCE, timings.end_s, timings.end_s + TAIL_S)
        return PhoneTimings((*timings.phones, tail), timings.language, timings.words)
    return timings


# --------------------------------------------------------------------------- 1c. wrong transcripts


def worst_stretch(wav: Path, transcript: str) -> float | None:
    """The lowest ``stretch_scores`` of ``transcript`` aligned to ``wav``; None when it cannot align."""
    samples, rate = read_wav(wav)
    audio = pcm16(padded(samples, rate), rate)  # as align_audio aligns it
    spoken = [w for w in text_to_phonemes(transcript) if not w.is_pause]
    for wide in (False, True):
        try:
            _, aligned = _align_words(_decoder(wide=wide), audio, spoken, "en")
        except SpeechError:
            continue
        return min(score for _, _, score in stretch_scores(aligned, PAD_S))
    return None


def bench_wrong_transcripts(items: list | None) -> None:
    print("\n1c. Wrong transcripts: worst stretch score (mean aligned score per frame over ≥ 0.5 s)")
    if not items:
        print("   table 1 was skipped: skipped too")
        return
    rng = np.random.default_rng(0)
    texts = [transcript for _, _, _, transcript, _ in items]
    header = ("utterance", "correct", "next text", "shuffled", "half replaced")
    rows, correct, wrong = [], [], []
    for k, (name, _, wav, transcript, _) in enumerate(items):
        words, other = transcript.split(), texts[(k + 1) % len(texts)].split()
        half = len(words) // 2
        variants = (
            transcript,
            " ".join(other),
            " ".join(rng.permutation(words)),
            " ".join([*words[:half], *other[: max(3, len(words) - half)]]),
        )
        scores = [worst_stretch(wav, t) for t in variants]
        correct += [] if scores[0] is None else [scores[0]]
        wrong += [s for s in scores[1:] if s is not None]
        rows.append((name, *("no alignment" if s is None else f"{s:.1f}" for s in scores)))
    TABLES.append(table(header, rows, "1c. Wrong transcripts"))
    print(
        f"   threshold align.MISMATCH_SCORE = {MISMATCH_SCORE:g}: correct ones ≥ {min(correct):.1f} "
        f"(all pass: {'yes' if min(correct) > MISMATCH_SCORE else 'NO'}), wrong ones ≤ {max(wrong):.1f} "
        f"(all refused: {'yes' if max(wrong) < MISMATCH_SCORE else 'NO'})"
    )


# --------------------------------------------------------------------------- 2. coarticulation quality


class LipGap:
    """The inner lip gap of a frame on the wire engine, as ``tests/speech/test_coarticulation.py``."""

    def __init__(self, rig) -> None:
        self.rig, self.engine = rig, make_engine(rig, "wire")

    def __call__(self, values: np.ndarray) -> float:
        """``quality.lip_gap`` of the pose, in % of the head height."""
        return lip_gap(self.rig, self.engine.deform(values)) / self.rig.scale * 100


def bench_coarticulation(rig, shared: Path | None) -> None:
    print(f"\n2. Coarticulation quality: coarticulate vs linear_clip (small_rig, wire engine, {FPS:g} fps)")
    gap = LipGap(rig)
    mouth = [j for j, n in enumerate(rig.channel_names) if channel_group(n) in ("lips", "jaw")]
    jaw, oo = rig.channel_names.index("jaw_open"), rig.channel_names.index("orbicularis_oris")
    sentences = [(f'"{s}"', "naive_timings", naive_timings(s)) for s in SENTENCES]
    if shared is None:
        print("   shared data speech/ not found: the LibriVox sentence is skipped")
    else:
        stem = shared / f"{LIBRIVOX}{UTTERANCES[0]}"
        text = Path(f"{stem}.txt").read_text().strip()
        words = text.split()
        sentences.append(
            (
                f'LibriVox {UTTERANCES[0]}: "{" ".join(words[:4])} …"',
                "reference",
                load_timings(f"{stem}.phone.json"),
            )
        )
    closed = CLOSED_GAP_REL * 100
    header = (
        "sentence",
        "timings",
        "method",
        "bilabials",
        "max gap at P B M %",
        f"closed (< {closed:.1f} %)",
        "min gap at AA AE %",
        "roughness",
        "ratio",
    )
    rows = []
    jaw_at: dict[str, dict[str, list[float]]] = {m: {v: [] for v in JAW_VOWELS} for m in ("coart", "linear")}
    rounding = {}
    for label, source, timings in sentences:
        clips = {"coart": coarticulate(timings, rig, FPS), "linear": linear_clip(timings, rig, FPS)}
        rough = {m: float((np.diff(c.values[:, mouth], n=2, axis=0) ** 2).sum()) for m, c in clips.items()}
        last = len(clips["coart"].values) - 1
        bilabials = [min(closure_frame(p), last) for p in timings.phones if p.label in BILABIAL]
        opens = [min(centre_frame(p), last) for p in timings.phones if p.label in OPEN_VOWELS]
        for method, clip in clips.items():
            gaps = [gap(clip.values[k]) for k in bilabials]
            open_gaps = [gap(clip.values[k]) for k in opens]
            for p in timings.phones:
                if p.label in JAW_VOWELS:
                    jaw_at[method][p.label].append(float(clip.values[min(centre_frame(p), last), jaw]))
            hits = sum(g < closed for g in gaps)
            rows.append(
                (
                    label if method == "coart" else "",
                    source if method == "coart" else "",
                    "coarticulate" if method == "coart" else "linear_clip",
                    f"{len(gaps)}",
                    f"{max(gaps):.2f}" if gaps else "-",
                    f"{hits}/{len(gaps)} ({hits / len(gaps):.0%})" if gaps else "-",
                    f"{min(open_gaps):.2f}" if open_gaps else "-",
                    f"{rough[method]:.4f}",
                    f"{rough['coart'] / rough['linear']:.3f}" if method == "coart" else "",
                )
            )
        if label == f'"{SENTENCES[2]}"':
            ts = [p for p in timings.phones if p.label == "T"]
            rounding = {
                timings.words[p.word]: {
                    m: float(c.values[min(centre_frame(p), last), oo]) for m, c in clips.items()
                }
                for p in ts
            }
    print(
        "   gaps: inner lip gap (upper_lip_inner to lower_lip_inner) on the frame nearest each phone's\n"
        f"   centre (a bilabial's: its closure's), % of the head height ({rig.scale:.2f} rig units);\n"
        "   closed = below the tests' "
        f"{closed:.1f} %;\n"
        "   roughness = summed squared second difference of the lips and jaw channels;\n"
        "   ratio = coarticulate / linear_clip roughness (below 1 is smoother)"
    )
    TABLES.append(table(header, rows, "2. Coarticulation"))
    targets = phone_targets(viseme_map("en"), list(JAW_VOWELS), rig)[:, jaw]
    parts = []
    for method in ("coart", "linear"):
        means = {v: float(np.mean(x)) if x else float("nan") for v, x in jaw_at[method].items()}
        present = all(jaw_at[method].values())
        order = "yes" if means["AA"] > means["EH"] > means["IY"] else "NO"
        cells = ", ".join(f"{v} {means[v]:.3f} (n={len(jaw_at[method][v])})" for v in JAW_VOWELS)
        name = "coarticulate" if method == "coart" else "linear_clip"
        parts.append(f"   {name}: {cells}; AA > EH > IY: {order if present else 'n/a (a vowel is missing)'}")
    print("jaw opening at vowel centres, mean jaw_open (rad) over the sentences above:")
    print("\n".join(parts))
    print("   targets: " + ", ".join(f"{v} {t:.3f}" for v, t in zip(JAW_VOWELS, targets, strict=True)))
    t_target = phone_targets(viseme_map("en"), ["T"], rig)[0, oo]
    print(f"/t/ rounding: orbicularis_oris at the centre of T (T's own target {t_target:.3f})")
    alone = {}
    for word in ("boot", "beet"):  # each word on its own too: no B after the T
        timings = naive_timings(word)
        t = next(p for p in timings.phones if p.label == "T")
        alone[word] = {
            m: float(c.values[min(centre_frame(t), len(c.values) - 1), oo])
            for m, c in (
                ("coart", coarticulate(timings, rig, FPS)),
                ("linear", linear_clip(timings, rig, FPS)),
            )
        }
    for where, values in ((f'in "{SENTENCES[2]}"', rounding), ("each word alone", alone)):
        cells = "; ".join(
            f"{word} coarticulate {v['coart']:.3f}, linear_clip {v['linear']:.3f}"
            for word, v in values.items()
        )
        boot, beet = values["boot"]["coart"], values["beet"]["coart"]
        print(f"   {where}: {cells}")
        print(f"      coarticulate boot > beet: {'yes' if boot > beet else 'NO'} ({boot - beet:+.3f})")


# --------------------------------------------------------------------------- 3. speed


def ten_seconds(timings: PhoneTimings) -> PhoneTimings:
    """``timings`` repeated back to back as needed, cut at CLIP_S (phones ending after it dropped, then a
    pause up to CLIP_S)."""
    phones: list[Phone] = []
    offset = 0.0
    while offset < CLIP_S:
        for p in timings.phones:
            if p.end_s + offset > CLIP_S:
                break
            phones.append(Phone(p.label, p.start_s + offset, p.end_s + offset, p.stress))
        offset += timings.end_s
    if phones[-1].end_s < CLIP_S - 1e-9:
        phones.append(Phone(SILENCE, phones[-1].end_s, CLIP_S))
    return PhoneTimings(tuple(phones), timings.language)


def bench_speed(rig, rounds: int) -> None:
    print("\n3. Speed")
    words = len(PARAGRAPH.split())
    paragraph = naive_timings(PARAGRAPH)
    clip_timings = ten_seconds(paragraph)
    speech = lip_sync(rig, text=PARAGRAPH, fps=FPS)
    cases = {
        "text": (lambda: naive_timings(PARAGRAPH), 10),
        "coart": (lambda: coarticulate(clip_timings, rig, FPS), 5),
        "linear": (lambda: linear_clip(clip_timings, rig, FPS), 5),
        "lip_sync": (lambda: lip_sync(rig, text=PARAGRAPH, fps=FPS), 3),
        "lip_sync linear": (lambda: lip_sync(rig, text=PARAGRAPH, fps=FPS, baseline=True), 3),
    }
    seconds = round_robin(cases, rounds)
    frames = {
        "text": n_frames(paragraph),
        "coart": n_frames(clip_timings),
        "linear": n_frames(clip_timings),
        "lip_sync": speech.clip.n_frames,
        "lip_sync linear": speech.clip.n_frames,
    }
    per = {case: s / frames[case] for case, s in seconds.items()}
    rows = [
        (f"text → phones (naive_timings), {words}-word paragraph", per["text"], "(no baseline)", None),
        (f"coarticulate, {CLIP_S:g} s at {FPS:g} fps", per["coart"], "linear_clip", per["linear"]),
        (f"baseline: linear_clip, {CLIP_S:g} s at {FPS:g} fps", per["linear"], "", None),
        (
            f"lip_sync from text, {words}-word paragraph, end to end",
            per["lip_sync"],
            "lip_sync baseline=True",
            per["lip_sync linear"],
        ),
        ("baseline: lip_sync baseline=True (linear), same text", per["lip_sync linear"], "", None),
    ]
    print(
        f"   paragraph: {words} words → {len(paragraph.spoken())} phones, {paragraph.end_s:.2f} s of speech "
        f"(naive timing), {frames['text']} frames at {FPS:g} fps;\n"
        f"   {CLIP_S:g} s clip: {len(clip_timings.phones)} phones, {frames['coart']} frames; lip_sync clip: "
        f"{speech.clip.n_frames} frames × {len(speech.clip.channels)} channels (+{TAIL_S:g} s tail);\n"
        f"   median of {rounds} rounds; times per {FPS:g} fps frame produced ({FPS:g} frames/s = real time); "
        "ratio = median / baseline"
    )
    print_table(rows)
    print("   whole calls, and speech seconds produced per second of computing (× real time):")
    for case, name in (
        ("text", "naive_timings (paragraph)"),
        ("coart", f"coarticulate ({CLIP_S:g} s)"),
        ("linear", f"linear_clip ({CLIP_S:g} s)"),
        ("lip_sync", "lip_sync (paragraph)"),
        ("lip_sync linear", "lip_sync baseline=True (paragraph)"),
    ):
        rate = frames[case] / FPS / seconds[case]
        print(f"   {name}: {seconds[case] * 1e3:.2f} ms, {rate:,.0f}× real time")


# --------------------------------------------------------------------------- main


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds (alignment timed once)")
    args = parser.parse_args()
    begin = time.perf_counter()
    load = os.getloadavg()
    print(f"load average at start {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min; 2 cores)")
    shared = shared_data_dir()
    if shared is not None and not (shared / "speech").is_dir():
        shared = None
    rig = small_rig()
    print(f"rig: small_rig(), {rig.n_vertices:,} vertices, {len(rig.channels)} channels")
    items = bench_alignment(shared, 1 if args.quick else 3)
    bench_audio_alone(rig, items)
    bench_wrong_transcripts(items)
    bench_coarticulation(rig, shared)
    bench_speed(rig, 5 if args.quick else 15)
    report.save("speech", TABLES)
    wall = time.perf_counter() - begin
    print(f"\nload average at the end {os.getloadavg()[0]:.2f}; benchmark wall time {wall:.0f} s")


if __name__ == "__main__":
    main()
