"""Helpers for tests that start the package's commands as child processes and interrupt them."""

from __future__ import annotations

import signal


def ctrl_c_able() -> None:
    """``Popen(preexec_fn=...)``: SIGINT back to its default in the child before it starts.

    A shell without job control starts its background jobs (``bash .ci/run &``) with SIGINT ignored, and every
    process inherits that; a Python started so installs no ``KeyboardInterrupt`` handler, so Ctrl-C sent by a test
    does nothing (a watch that never stops, a sweep that runs to the end). The child gets the disposition a
    terminal's Ctrl-C meets.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)
