"""Named errors of the survey readers; each is a ``ValueError``, so the command line reports it as bad input (exit 1)."""

from __future__ import annotations

__all__ = ["SurveyFileError", "TruncatedFileError", "NoPingsError", "MissingLayerError", "UncertaintyLayerError",
           "DifferentShipsError", "SurveyOffMapError"]


class SurveyFileError(ValueError):
    """A file is not of a format LOST reads, or not one the reader can make sense of; the message names the file."""


class TruncatedFileError(SurveyFileError):
    """A file ends inside a structure its own header promises (a datagram, a dataset)."""


class NoPingsError(SurveyFileError):
    """Nothing usable is left after the counted skips (no ping with a position, every beam flagged)."""


class MissingLayerError(SurveyFileError):
    """A grid file lacks a layer the caller asked for (a BAG without its uncertainty layer)."""


class UncertaintyLayerError(SurveyFileError):
    """A grid's uncertainty layer is not one: another shape than its depth, negative or infinite values, units not metres."""


class DifferentShipsError(SurveyFileError):
    """Pings of different ships (or sonars) given as one survey to navigate: their positions are no one track."""


class SurveyOffMapError(SurveyFileError):
    """A survey to navigate lies outside its map: no position of its track falls on the grid."""
