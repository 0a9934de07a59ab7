"""``mimetic view``: the web viewer, served until Ctrl-C."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Literal

import typer
from rich.text import Text

from mimetic.cli.app import command, stderr, stdout
from mimetic.engines import ENGINES
from mimetic.errors import MimeticError


@command()
def view(
    source: Path = typer.Argument(
        ..., metavar="RIG", help="A .mrig rig, or a mesh (.obj .ply .stl .glb) to pick landmarks on."
    ),
    port: int = typer.Option(8080, "--port", min=1, max=65535, help="The port to serve the page on."),
    host: str = typer.Option(
        "127.0.0.1", "--host", help="The address to listen on (0.0.0.0 shares the page on your network)."
    ),
    engine: Literal[ENGINES] = typer.Option("wire", "--engine", help="The engine shown first."),
    clip: Path | None = typer.Option(None, "--clip", help="A clip JSON to load on the timeline."),
    audio: Path | None = typer.Option(None, "--audio", help="The clip's sound (WAV), played with it."),
    landmarks: Path | None = typer.Option(
        None,
        "--landmarks",
        help="Where picked landmarks are saved (default: beside SOURCE).",
    ),
    capture: Path | None = typer.Option(
        None,
        "--capture",
        metavar="VIDEO",
        help="Play a video's face on the rig as it arrives, at the video's pace: the first 0.5 s "
        "calibrate (hold a neutral face). A camera device such as /dev/video0 is passed on the same "
        "way (untested: no camera was at hand). Needs the [track] extra.",
    ),
    speak: Path | None = typer.Option(
        None,
        "--speak",
        metavar="AUDIO",
        help="Lip-sync a WAV file on the rig as it arrives, at its pace, standing in for a microphone "
        "(English phones recognised live, 0.1 s look-ahead; the sound is not played). Needs the "
        "[speech] extra.",
    ),
) -> None:
    """Open RIG in a local web page: sliders, expressions, keys and playback, landmark picking.

    Needs the [view] extra (pip install 'mimetic[view]'). Stop it with Ctrl-C.

    Examples:

    \b
      mimetic view head.mrig
      mimetic view head.mrig --clip speech.clip.json --audio speech.wav --port 8081
      mimetic view scan.obj --landmarks scan.json
      mimetic view head.mrig --capture take.mp4
      mimetic view head.mrig --speak hello.wav
    """
    from mimetic.view.web import PREPARE_NOTE, check_capture, check_speak, start

    if not source.is_file():  # nothing to show: fail before serving a page
        raise MimeticError(f"{source}: no such file")
    for given, option in ((clip, "--clip"), (audio, "--audio")):
        if given is not None and not given.is_file():
            raise MimeticError(f"{option} {given}: no such file")
    if capture is not None and speak is not None:
        raise MimeticError("give --capture or --speak, not both: each drives the face live")
    if capture is not None:
        check_capture(source, capture)
    if speak is not None:
        check_speak(source, speak)
    if engine in PREPARE_NOTE:
        stderr.print(f"preparing the {engine} engine: {PREPARE_NOTE[engine]}, once")
    viewer = start(
        source,
        host=host,
        port=port,
        engine=engine,
        clip=clip,
        audio=audio,
        landmarks_out=landmarks,
        capture=capture,
        speak=speak,
    )
    if viewer.error:  # a rig that cannot be read: said here and in the page, which stays up to say it
        stderr.print(Text.assemble(("error: ", "bold red"), viewer.error))
        stderr.print("the page shows the error too; Ctrl-C to stop")
    shown = "localhost" if host in ("127.0.0.1", "::1") else host
    stdout.print(f"mimetic view: http://{shown}:{viewer.server.get_port()}  (Ctrl-C to stop)")
    told = False  # the capture's end was said
    try:
        while True:
            time.sleep(0.25 if viewer.live is not None else 1.0)
            status = viewer.live.status if viewer.live is not None else None
            if status is not None and status.done and not told:
                told = True
                if status.state == "failed":
                    stderr.print(Text.assemble(("error: ", "bold red"), status.error))
                    stderr.print("the page shows the error too; Ctrl-C to stop")
                else:
                    stderr.print(f"live {'lip sync' if speak else 'capture'} {status.text()}")
    finally:
        viewer.stop()
