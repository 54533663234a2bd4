"""The one exception class of example_pcl, and how nodes log its messages once per kind."""
import re


class PerceptionError(ValueError):
    """Input or a processing step failed in a way the caller can act on.

    Raised for malformed PointCloud2 messages and PCD files, and for domain failures: no patch
    selected, no plane found, too few points, a fit that did not converge. Its message says what
    went wrong and, where there is one, what to do next. Nodes log it and keep running; service
    handlers answer ``success=False`` with the message.
    """


def warning_kind(error: Exception) -> str:
    """A key grouping errors of one kind: the message with its numbers and quoted names blanked."""
    return re.sub(r"'[^']*'", "'…'", re.sub(r"\d+", "N", str(error)))


class OncePerKind:
    """Which kinds of error (:func:`warning_kind`) were seen: nodes log the first of each kind as a
    warning and the rest quietly (counted, or at debug level), so a publisher sending the same bad
    message at 30 Hz cannot flood the log. Unlocked: two threads meeting a new kind at once may
    both be told first (two warnings, never none)."""

    def __init__(self):
        self._seen = set()

    def first(self, error: Exception) -> bool:
        """True the first time an error of this kind is seen, False after."""
        kind = warning_kind(error)
        if kind in self._seen:
            return False
        self._seen.add(kind)
        return True
