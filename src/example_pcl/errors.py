"""The one exception class of example_pcl, and how nodes group its messages for logging."""
import re


class PerceptionError(ValueError):
    """Input or a processing step failed in a way the caller can act on.

    Raised for malformed PointCloud2 messages and PCD files, and for domain failures: no patch
    selected, no plane found, too few points, a fit that did not converge. Its message says what
    went wrong and, where there is one, what to do next. Nodes log it and keep running; service
    handlers answer ``success=False`` with the message.
    """


def require_positive(config, names):
    """Raises PerceptionError naming the first of config's fields `names` that is not > 0."""
    for name in names:
        value = getattr(config, name)
        if not value > 0:
            raise PerceptionError(f"{type(config).__name__}.{name} must be > 0, got {value}")


def warning_kind(error: Exception) -> str:
    """A key grouping errors of one kind: the message with its numbers and quoted names blanked.

    Nodes log the first error of each kind as a warning and count the rest, so a publisher
    sending the same bad message at 30 Hz cannot flood the log.
    """
    return re.sub(r"'[^']*'", "'…'", re.sub(r"\d+", "N", str(error)))


class OncePerKind:
    """Logs the first message of each kind (warning_kind) through `first`, later ones through
    `again` (e.g. rospy.logwarn and rospy.logdebug; None: not at all, only counted), and counts
    them all by kind."""

    def __init__(self, first, again=None):
        self._first, self._again = first, again
        self.counts = {}

    def __call__(self, what, error):
        """Logs "what: error"; returns True when it was the first of its kind."""
        kind = warning_kind(f"{what}: {error}")
        self.counts[kind] = self.counts.get(kind, 0) + 1
        if self.counts[kind] == 1:
            later = "logged at debug level" if self._again is not None else "counted, not logged"
            self._first("%s: %s (further ones of this kind are %s)", what, error, later)
            return True
        if self._again is not None:
            self._again("%s: %s", what, error)
        return False
