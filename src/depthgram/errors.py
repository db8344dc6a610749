"""Errors meant for people: each names the file, the frame and what was expected."""

from __future__ import annotations

__all__ = ["DepthgramError", "InputError", "MissingExtraError"]


class DepthgramError(Exception):
    """Base of every error depthgram raises on purpose. The command line prints its message."""


class InputError(DepthgramError, ValueError):
    """Bad input: unreadable or truncated file, wrong shape or dtype, empty folder, bad value."""


class MissingExtraError(DepthgramError, ImportError):
    """An optional dependency is not installed; the message names the extra that installs it."""
