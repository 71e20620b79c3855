"""What reading a navigation log kept, skipped and why: :class:`LoadReport` (:func:`lost.host.io.navlog.read_navlog`'s second value)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

__all__ = ["LoadReport"]


@dataclass(frozen=True)
class LoadReport:
    """What reading a navigation log (and its sonar side file) kept, skipped and why.

    Attributes
    ----------
    path : str
        The navigation log.
    rows : int
        Data rows in the log.
    records : int
        Records kept (``rows`` less the skipped ones).
    nan_counts : dict[str, int]
        Missing readings (empty or NaN cells) per column read, kept rows only.
    skipped_rows : tuple of (int, str)
        ``(data row, reason)`` for each row left out; data rows count from 0 after the header.
    unknown_columns : tuple of str
        Columns not in the documented layout, not read.
    warnings : tuple of str
        Implausible readings found and kept (position jumps faster than any ship); the command line
        puts them in the run's report.
    notes : tuple of str
        Decisions worth knowing: projections, north conversion, absent optional columns, ignored
        duplicate forms.
    sonar_path : str or None
        The sonar side file, if one was read.
    soundings : int
        Rows of the sonar file.
    soundings_used : int
        Soundings gridded into a patch.
    soundings_implausible : int
        Soundings whose depth no sea floor has (more than ``SOUNDING_ABOVE_SURFACE_M`` above the
        surface, deeper than ``lost.host.io.filecheck.DEEPEST_M``).
    soundings_without_value : int
        Soundings with an empty or NaN time/record, offset or depth.
    soundings_unmatched : int
        Soundings whose time or record index matches no row of the log.
    soundings_of_skipped_records : int
        Soundings belonging to a skipped row.
    soundings_outside_patch : int
        Soundings farther from the vehicle than the patch reaches.
    records_with_sonar : int
        Records that got a patch.
    """

    path: str
    rows: int
    records: int
    nan_counts: dict[str, int]
    skipped_rows: tuple[tuple[int, str], ...] = ()
    unknown_columns: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    sonar_path: str | None = None
    soundings: int = 0
    soundings_used: int = 0
    soundings_without_value: int = 0
    soundings_implausible: int = 0
    soundings_unmatched: int = 0
    soundings_of_skipped_records: int = 0
    soundings_outside_patch: int = 0
    records_with_sonar: int = 0

    def summary(self) -> str:
        """A few lines of plain text for the command line."""
        lines = [f"{self.path}: {self.rows} rows, {self.records} records kept"]
        if self.skipped_rows:
            reasons = Counter(reason for _, reason in self.skipped_rows)
            for reason, count in reasons.items():
                rows = [str(r) for r, why in self.skipped_rows if why == reason]
                shown = ", ".join(rows[:5]) + (", ..." if len(rows) > 5 else "")
                lines.append(f"  skipped {count} row(s), {reason}: data row(s) {shown}")
        missing = {c: n for c, n in self.nan_counts.items() if n}
        if missing:
            lines.append("  missing readings (kept as NaN): " + ", ".join(f"{c} {n}" for c, n in missing.items()))
        if self.unknown_columns:
            lines.append("  unknown columns, not read: " + ", ".join(self.unknown_columns))
        lines += [f"  note: {n}" for n in self.notes]
        lines += [f"  warning: {w}" for w in self.warnings]
        if self.sonar_path is not None:
            lines.append(
                f"{self.sonar_path}: {self.soundings} soundings, {self.soundings_used} gridded into "
                f"{self.records_with_sonar} patch(es)"
            )
            for label, count in (
                ("without a value (empty or NaN)", self.soundings_without_value),
                ("with a depth no sea floor has", self.soundings_implausible),
                ("matching no record", self.soundings_unmatched),
                ("of skipped records", self.soundings_of_skipped_records),
                ("beyond the patch", self.soundings_outside_patch),
            ):
                if count:
                    lines.append(f"  not used: {count} {label}")
        return "\n".join(lines)
