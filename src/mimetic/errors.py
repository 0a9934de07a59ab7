"""Error types: bad input a user can fix raises a ``MimeticError`` subclass.

Each subclass is also a ``ValueError`` so generic handlers still catch it. The CLI shows
the message of a ``MimeticError`` as one line, without a traceback.
"""


class MimeticError(Exception):
    """Bad input a user can fix; the message says what is wrong and how to fix it."""


class MeshError(MimeticError, ValueError):
    """A mesh that cannot be used: unreadable, empty, NaN coordinates, too small, wrong units."""


class LandmarkError(MimeticError, ValueError):
    """Landmarks missing, duplicated, unknown or off the surface."""


class RigError(MimeticError, ValueError):
    """A rig whose contents are inconsistent (a muscle on a missing vertex, bad weights)."""


class RigFormatError(MimeticError, ValueError):
    """A ``.mrig`` file that is corrupt, truncated, or written by a newer format version."""


class ActivationError(MimeticError, ValueError):
    """Activations for unknown channels, of the wrong shape, or outside a channel's range."""


class ControlError(MimeticError, ValueError):
    """An unknown descriptive control, or a slider value of the wrong shape or outside its range."""


class ExpressionError(MimeticError, ValueError):
    """An unknown expression, a malformed library file, or a bad blend weight."""


class RenderError(MimeticError, RuntimeError):
    """Offscreen rendering is unavailable (e.g. a missing system library)."""


class SpeechError(MimeticError, ValueError):
    """Unknown phonemes or words, a malformed timing file, audio that cannot be aligned, an unknown
    language or viseme map."""


class MissingExtraError(MimeticError, ImportError):
    """An optional dependency is not installed; the message names the extra to install."""


def install_hint(extra: str) -> str:
    """The command that installs one of mimetic's extras (e.g. "track") where mimetic runs from:
    ``pip install -e '.[track]'`` in a source checkout (run in its folder), else
    ``pip install 'mimetic[track]'``."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    pyproject = root / "pyproject.toml"
    if pyproject.is_file() and 'name = "mimetic"' in pyproject.read_text(encoding="utf-8", errors="replace"):
        return f"pip install -e '.[{extra}]' (in {root})"
    return f"pip install 'mimetic[{extra}]'"


class MimeticWarning(UserWarning):
    """Input that is suspect but usable, or a solver that did not converge."""
