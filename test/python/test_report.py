import json
import math

import numpy as np

from multisession_mapper_eval import report


def test_clean_makes_strict_json():
    value = {'a': np.float32(0.5), 'b': float('nan'), 'c': [np.int64(3), math.inf],
             'd': np.array([1.0, 2.0]), 'e': np.bool_(True)}
    text = json.dumps(report.clean(value), allow_nan=False)
    assert json.loads(text) == {'a': 0.5, 'b': None, 'c': [3, None], 'd': [1.0, 2.0], 'e': True}


def test_table_format():
    assert report._table(['a', 'b'], [[1, 2]]) == '| a | b |\n|---|---|\n| 1 | 2 |'
    assert report._fmt(None) == '-' and report._fmt(0.12345) == '0.123'
