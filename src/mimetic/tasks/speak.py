"""``mimetic speak``: lip sync from text, phone timings or audio, delivered as any clip output."""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

from mimetic.speech.phones import LANGUAGES
from mimetic.speech.visemes import BUILT_IN
from mimetic.tasks.animate import PlayOptions
from mimetic.tasks.base import Progress, Result, Task, TaskError, announce, check_output, option
from mimetic.tasks.outputs import CLIPS, SCENES, VIDEOS

TIMING_FILES = (".textgrid", ".csv", ".json")
AUDIO_FILES = (".wav",)
SILENT_VIDEO_NOTE = (
    "the video is silent: text alone has no sound; add --synthesize (espeak-ng) or --audio for speech"
)


def held_expressions(items) -> tuple[tuple[str, float], ...]:
    """``NAME``, ``NAME:WEIGHT`` or ``NAME=WEIGHT`` items → ((name, weight), ...)."""
    from mimetic.tasks.parsing import weights

    return weights([item.replace(":", "=", 1) if "=" not in item else item for item in items])


@dataclass(frozen=True)
class SpeakOptions(PlayOptions):
    """What is said and how (see ``option`` for the fields' metadata)."""

    text: str | None = option(None, "What is said (the transcript, with audio).")
    text_file: Path | None = option(None, "Read the text from a file (any common encoding).")
    timings: Path | None = option(
        None, "Phone timings: Praat/MFA TextGrid, CSV or JSON (phoneme, start, end)."
    )
    audio: Path | None = option(
        None,
        "A recording (WAV): aligned to the text offline (English without text: recognised); in an MP4.",
    )
    force: bool = option(False, "Align the text even where the recording does not say it.")
    synthesize: bool = option(False, "Speak the text with the espeak-ng program and sync to its sound.")
    language: str = option("en", "en (English) or nso (Northern Sotho, Sesotho sa Leboa).", choices=LANGUAGES)
    visemes: str | None = option(
        None, "Viseme map: en, nso, mpeg4 or a map .json (default: the language's).", names=BUILT_IN
    )
    rate: float = option(1.0, "Speaking rate for text alone.", minimum=0.2, maximum=5.0)
    jaw: float = option(1.0, "Jaw intensity (JALI dial).", minimum=0.0, maximum=2.0)
    lips: float = option(1.0, "Lip intensity (JALI dial).", minimum=0.0, maximum=2.0)
    eyes: bool = option(True, "Add blinks and small gaze saccades.")
    seed: int = option(0, "Seed of the blinks and saccades.")
    baseline: bool = option(False, "Linear interpolation between visemes instead of coarticulation.")
    expressions: tuple[tuple[str, float], ...] = option(
        (),
        "Hold an expression under the lip sync (repeatable); bilabials still close the lips.",
        flag="--expr",
        metavar="NAME[:WEIGHT]",
        parse=held_expressions,
        cli_type=list[str],
    )
    timings_out: Path | None = option(
        None, "Also write the phone timings (.TextGrid, .csv or .json).", batch=False
    )
    audio_out: Path | None = option(
        None, "Keep the synthesized speech (with synthesize) as this WAV file.", batch=False
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.text is not None and self.text_file is not None:
            raise TaskError("give text or text_file, not both")
        if self.audio_out is not None and not self.synthesize:
            raise TaskError(
                f"audio_out={str(self.audio_out)!r} keeps synthesized speech: give it together with "
                "synthesize (recorded audio is already a file of its own)"
            )


def run(source: Path, output: Path, options: SpeakOptions, progress: Progress | None = None) -> Result:
    """Lip-sync the rig ``source`` (``speech.lipsync.lip_sync``) and write ``output`` as
    ``outputs.write_clip`` does (a video with the sound, a scene, a clip file); the phone timings
    too when ``timings_out`` is given, and the synthesized sound when ``audio_out`` is. The result
    names only files that exist after the run, and its notes say when a video is silent or Sepedi
    was synthesized with another language's voice."""
    from mimetic.errors import SpeechError
    from mimetic.inputs import read_text
    from mimetic.speech.lipsync import lip_sync
    from mimetic.speech.timings import save_timings
    from mimetic.speech.visemes import load_viseme_map
    from mimetic.tasks.outputs import write_clip
    from mimetic.tasks.prepared import prepared_rig

    check_output(output, CLIPS)
    if options.timings_out is not None:
        check_output(options.timings_out, TIMING_FILES, "timing file")
    if options.audio_out is not None:
        check_output(options.audio_out, AUDIO_FILES, "audio file")
    text = options.text
    if options.text_file is not None:
        text = read_text(options.text_file, SpeechError, "text")
    TASK.check(options)
    prepared = prepared_rig(source)
    visemes = options.visemes
    if visemes is not None and visemes not in BUILT_IN:
        visemes = load_viseme_map(visemes, channels=prepared.rig)
    announce(progress, "lip sync")
    with tempfile.TemporaryDirectory(prefix="mimetic-speak-") as scratch:
        speech = lip_sync(
            prepared.rig,
            text=text,
            timings=options.timings,
            audio=options.audio,
            synthesize_to=Path(scratch) / "synthesized.wav" if options.synthesize else None,
            language=options.language,
            fps=options.fps,
            visemes=visemes,
            jaw=options.jaw,
            lips=options.lips,
            rate=options.rate,
            eyes=options.eyes,
            seed=options.seed,
            baseline=options.baseline,
            force=options.force,
        )
        clip = speech.clip
        if options.expressions:
            from mimetic.animate.expressions import blend
            from mimetic.speech.lipsync import under_expression

            pose = blend(prepared.rig, options.expressions)
            clip = under_expression(clip, speech.timings, prepared.rig, pose, visemes=visemes)
        written = [
            write_clip(
                prepared,
                clip,
                output,
                engine=options.engine,
                size=options.size,
                audio=speech.audio,
                progress=progress,
            )
        ]
        if options.audio_out is not None:
            written.append(_keep(speech.audio, options.audio_out))
    if options.timings_out is not None:
        written.append(save_timings(speech.timings, options.timings_out))
    phones = len(speech.timings.spoken())
    summary = f"{clip.n_frames} frames at {options.fps:g} fps, {phones} phones, {speech.source}"
    notes = speech.notes
    if output.suffix.lower() in VIDEOS and speech.audio is None:
        notes = (*notes, SILENT_VIDEO_NOTE)
    return Result(tuple(Path(p) for p in written), summary, notes=notes)


def _keep(sound: Path, out: Path) -> Path:
    """Copy the scratch WAV ``sound`` to ``out`` atomically."""
    import shutil

    from mimetic.atomic import atomic_path

    with atomic_path(out) as tmp:
        shutil.copyfile(sound, tmp)
    return Path(out)


TASK = Task(
    "speak",
    SpeakOptions,
    run,
    (*SCENES, *VIDEOS, ".json", ".csv"),
    source="rig",
    required=(("text", "text_file", "timings", "audio"),),
)
