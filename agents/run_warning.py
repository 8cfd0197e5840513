"""The warning of a run: what ``vcnc-train`` did on its own that the user should know."""

import warnings

__all__ = ["RunWarning", "note"]


class RunWarning(UserWarning):
    """Something vcnc-train did on its own that the user should know (rounding, fallback, roll-back)."""


def note(message: str) -> None:
    """Warn ``message`` as a :class:`RunWarning` attributed to the caller's caller."""
    warnings.warn(message, RunWarning, stacklevel=3)
