"""Tests of example_pcl.errors: errors grouped by kind, each kind logged once."""
from example_pcl.errors import OncePerKind, PerceptionError, warning_kind


def test_warning_kind_groups_errors_of_one_kind():
    """Errors differing only in numbers or names share a kind (one warning each kind); different kinds do not."""
    a = PerceptionError("data has 10 bytes, height 1 x row_step 16 needs 16")
    b = PerceptionError("data has 99 bytes, height 2 x row_step 64 needs 128")
    c = PerceptionError("big-endian PointCloud2 messages are not supported")
    assert warning_kind(a) == warning_kind(b) != warning_kind(c)


def test_once_per_kind_logs_the_first_of_each_kind_and_the_rest_quietly():
    """The first error of each kind goes to `first`, later ones of that kind (whatever their numbers
    and names) to `again`; all are counted by kind."""
    first, again = [], []
    once = OncePerKind(lambda *a: first.append(a[0] % a[1:]), lambda *a: again.append(a[0] % a[1:]))
    errors = [PerceptionError("frame 'a' has 3 points"), PerceptionError("frame 'b' has 7 points"),
              PerceptionError("no table"), PerceptionError("frame 'c' has 1 points"), PerceptionError("no table")]
    assert [once("dropped", e) for e in errors] == [True, False, True, False, False]
    assert first == ["dropped: frame 'a' has 3 points (further ones of this kind are logged at debug level)",
                     "dropped: no table (further ones of this kind are logged at debug level)"]
    assert again == ["dropped: frame 'b' has 7 points", "dropped: frame 'c' has 1 points", "dropped: no table"]
    assert sorted(once.counts.values()) == [2, 3]


def test_once_per_kind_without_again_only_counts():
    """With no `again`, later errors of a kind are counted, not logged, and the first says so."""
    first = []
    once = OncePerKind(lambda *a: first.append(a[0] % a[1:]))
    assert [once("x", PerceptionError("bad 1")), once("x", PerceptionError("bad 2"))] == [True, False]
    assert first == ["x: bad 1 (further ones of this kind are counted, not logged)"]
    assert list(once.counts.values()) == [2]


def test_require_positive_names_the_config_and_the_first_bad_field():
    """require_positive passes when every named field is > 0 and otherwise names the first bad one."""
    import dataclasses

    import pytest

    from example_pcl.errors import PerceptionError, require_positive

    @dataclasses.dataclass
    class Config:
        a: float = 1.0
        b: int = 0
        c: float = -1.0

    require_positive(Config(), ("a",))
    with pytest.raises(PerceptionError, match=r"Config\.b must be > 0, got 0"):
        require_positive(Config(), ("a", "b", "c"))
