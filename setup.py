"""Python package of example_pcl, installed by catkin_python_setup() (never run by hand)."""
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=["example_pcl"], package_dir={"": "src"}))
