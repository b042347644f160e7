"""pytest setup for the evaluator tests: import the package from the source tree."""

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, '..', '..', 'python'))
sys.path.insert(0, HERE)

import pytest  # noqa: E402

import synthetic_case  # noqa: E402


@pytest.fixture(scope='session')
def synthetic_dirs(tmp_path_factory):
    """(map_dir, truth_dir) of the hand-made case in synthetic_case.py (built once)."""
    root = tmp_path_factory.mktemp('synthetic')
    map_dir, truth_dir = str(root / 'map'), str(root / 'sim')
    synthetic_case.make_truth(truth_dir)
    synthetic_case.make_map(map_dir)
    return map_dir, truth_dir
