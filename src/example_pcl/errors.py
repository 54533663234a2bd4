"""The one exception class of example_pcl."""


class PerceptionError(ValueError):
    """Input or a processing step failed in a way the caller can act on.

    Raised for malformed PointCloud2 messages and PCD files, and for domain failures: no patch
    selected, no plane found, too few points, a fit that did not converge. Its message says what
    went wrong and, where there is one, what to do next. Nodes log it and keep running; service
    handlers answer ``success=False`` with the message.
    """
