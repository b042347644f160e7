# Python modules of the package (evaluation); used by catkin_python_setup(), not run directly.
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(
    packages=['multisession_mapper_eval'],
    package_dir={'': 'python'},
))
