"""Tests of pytest.ini: a deprecated call from our code fails the suite, a library's own does not."""
import warnings

import pytest


@pytest.mark.parametrize("module", ["example_pcl.conversions", "example_pcl", "test_conversions", "conftest",
                                    "fuzz.pcd_mutations", "find_can_helpers"])
@pytest.mark.parametrize("category", [DeprecationWarning, PendingDeprecationWarning])
def test_deprecation_from_our_code_is_an_error(module, category):
    """A (pending) deprecation warning attributed to one of our modules is raised as an error."""
    with pytest.raises(category):
        warnings.warn_explicit("deprecated", category, "ours.py", 1, module=module)


@pytest.mark.parametrize("module", ["numpy.core.fromnumeric", "rospy.topics", "not_example_pcl"])
def test_deprecation_inside_a_library_stays_a_warning(module):
    """A deprecation warning a library raises about its own code is reported, not raised."""
    with pytest.warns(DeprecationWarning):
        warnings.warn_explicit("deprecated", DeprecationWarning, "theirs.py", 1, module=module)
