"""Starting a process that a test stops with Ctrl-C (SIGINT)."""

from __future__ import annotations

import signal


def sigint_as_in_a_terminal() -> None:
    """``preexec_fn`` for such a process: SIGINT back to its default action, so that Python installs its Ctrl-C
    handler. A shell without job control starts background commands with SIGINT ignored and children inherit that
    (a test suite run as ``./scripts/test &`` from a script saw clm-studio ignore every Ctrl-C); a terminal's
    foreground process never has it ignored."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
