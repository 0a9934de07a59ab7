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


class MissingExtraError(MimeticError, ImportError):
    """An optional dependency is not installed; the message names the extra to install."""


class MimeticWarning(UserWarning):
    """Input that is suspect but usable, or a solver that did not converge."""
