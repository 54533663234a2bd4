"""Where example_pcl's files are: the package directory, found as ``rospack find`` finds it."""
import os


def package_path(*parts: str) -> str:
    """A path inside the example_pcl package: ``$(rospack find example_pcl)/parts...``.

    Works from a devel or an install space alike (rospkg looks the package up on
    ROS_PACKAGE_PATH); without rospkg, or with the package not on that path, this source tree.
    """
    try:
        import rospkg

        root = rospkg.RosPack().get_path("example_pcl")
    except Exception:  # rospkg missing or the package not on ROS_PACKAGE_PATH: use this checkout
        root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return os.path.join(root, *parts)


def default_scene_path() -> str:
    """The bundled scene every node loads by default: ``$(rospack find example_pcl)/data/test_pcd.pcd``."""
    return package_path("data", "test_pcd.pcd")
