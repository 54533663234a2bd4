"""Tests of example_pcl.errors: errors grouped by kind, each kind logged once."""
from example_pcl.errors import OncePerKind, PerceptionError, warning_kind


def test_warning_kind_groups_errors_of_one_kind():
    """Errors differing only in numbers or names share a kind (one warning each kind); different kinds do not."""
    a = PerceptionError("data has 10 bytes, height 1 x row_step 16 needs 16")
    b = PerceptionError("data has 99 bytes, height 2 x row_step 64 needs 128")
    c = PerceptionError("big-endian PointCloud2 messages are not supported")
    assert warning_kind(a) == warning_kind(b) != warning_kind(c)


def test_once_per_kind_says_first_once_for_each_kind():
    """The first error of each kind is first, later ones of that kind are not, whatever their numbers and names."""
    seen = OncePerKind()
    errors = [PerceptionError("frame 'a' has 3 points"), PerceptionError("frame 'b' has 7 points"),
              PerceptionError("no table"), PerceptionError("frame 'c' has 1 points"), PerceptionError("no table")]
    assert [seen.first(e) for e in errors] == [True, False, True, False, False]
    assert OncePerKind().first(errors[1])  # each node (each instance) keeps its own
