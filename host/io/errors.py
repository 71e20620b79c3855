"""Named errors of the survey readers; each is a ``ValueError``, so the command line reports it as bad input (exit 1)."""

from __future__ import annotations

__all__ = ["SurveyFileError", "TruncatedFileError", "NoPingsError", "MissingLayerError"]


class SurveyFileError(ValueError):
    """A file is not of a format LOST reads, or not one the reader can make sense of; the message names the file."""


class TruncatedFileError(SurveyFileError):
    """A file ends inside a structure its own header promises (a datagram, a dataset)."""


class NoPingsError(SurveyFileError):
    """Nothing usable is left after the counted skips (no ping with a position, every beam flagged)."""


class MissingLayerError(SurveyFileError):
    """A grid file lacks a layer the caller asked for (a BAG without its uncertainty layer)."""
