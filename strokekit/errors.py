"""Errors a user can act on. The CLI turns each into one line and an exit code."""

from __future__ import annotations


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
    """An impossible combination of options."""

    exit_code = 2
