"""The ``mimetic`` console script: the command line (``mimetic.cli``), with Ctrl-C while it loads
said in one line too (loading the commands takes a few seconds; exit code 130, as anywhere else)."""

from __future__ import annotations

import sys


def main() -> None:
    """Load and run the ``mimetic`` command."""
    try:
        from mimetic.cli import app
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        raise SystemExit(130) from None
    app()
