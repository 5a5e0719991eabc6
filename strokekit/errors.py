"""Errors a user can act on. The CLI turns each into one line and an exit code."""

from __future__ import annotations

import difflib
import threading


class StrokekitError(Exception):
    """Base of all errors meant for the user. `exit_code` is what the CLI returns."""

    exit_code = 1

    def __init__(self, message: str, path: str | None = None):
        self.path = str(path) if path is not None else None
        super().__init__(f"{self.path}: {message}" if self.path else message)


class InputError(StrokekitError):
    """A file or value given to us is unusable (missing, empty, NaN, inconsistent)."""

    exit_code = 1


class UsageError(StrokekitError):
    """An impossible option value or combination. `option`: the options field the message is
    about, named first in it (the CLI names its command-line flag instead)."""

    exit_code = 2

    def __init__(self, message: str, path: str | None = None, option: str | None = None):
        self.option = option
        super().__init__(message, path)


def did_you_mean(word, known) -> str:
    """"did you mean 'x'? " for the one of `known` closest to a mistyped `word`, else ""."""
    close = difflib.get_close_matches(str(word), [str(k) for k in known], n=1)
    return f"did you mean '{close[0]}'? " if close else ""


class hold_interrupts:
    """Ctrl-C during the block is held until the block ends, then raised as KeyboardInterrupt.
    For code that would swallow or transform it: trimesh catches BaseException around its optional
    imports and between loaders (the interrupt would be lost and an optional module marked
    missing); open3d's module init turns it into ImportError("initialization failed") (the
    Occluder would fall back to embreex, other bytes, and the run would go on). Only in the main
    thread (where Python runs signal handlers) and only when Ctrl-C raises KeyboardInterrupt
    (Python's default handler: not when SIGINT is ignored, as in a background job)."""

    def __enter__(self):
        import signal

        self.pressed, self.previous = False, None
        if threading.current_thread() is threading.main_thread() \
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self.previous = signal.signal(signal.SIGINT, self._hold)
        return self

    def _hold(self, signum, frame):
        self.pressed = True

    def __exit__(self, *exc):
        import signal

        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        if self.pressed:
            raise KeyboardInterrupt
        return False
