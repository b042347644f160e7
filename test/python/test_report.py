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


def test_breakdown_tables():
    assert report._breakdown_tables(None) == []
    b = {'by_range': [{'from_m': 0.0, 'to_m': 10.0, 'sa': 0.5, 'static_points': 2,
                       'low_da': None, 'low_points': 0, 'high_da': 1.0, 'high_points': 1},
                      {'from_m': 40.0, 'to_m': None, 'sa': None, 'static_points': 0,
                       'low_da': 0.25, 'low_points': 4, 'high_da': None, 'high_points': 0}],
         'low_by_presence': [{'present_in': [], 'objects': 1, 'points': 3, 'da': None},
                             {'present_in': ['s00', 's01'], 'objects': 2, 'points': 5,
                              'da': 0.4}],
         'by_class': [{'class': 0, 'name': 'terrain', 'static_points': 8, 'static_kept': 6,
                       'low_points': 0, 'low_removed': 0, 'high_points': 0, 'high_removed': 0,
                       'sa': 0.75, 'low_da': None, 'high_da': None},
                      {'class': 10, 'name': 'pedestrian', 'static_points': 0,
                       'static_kept': 0, 'low_points': 0, 'low_removed': 0, 'high_points': 4,
                       'high_removed': 3, 'sa': None, 'low_da': None, 'high_da': 0.75}]}
    text = '\n'.join(report._breakdown_tables(b))
    assert '| 0-10 | 50.00 | 2 | - | 0 | 100.00 | 1 |' in text
    assert '| 40- | - | 0 | 25.00 | 4 | - | 0 |' in text
    assert '| - | 1 | 3 | - |' in text
    assert '| s00 + s01 | 2 | 5 | 40.00 |' in text
    assert '| terrain | 75.00 | 8 | 2 | - | 0 | 0 | - | 0 | 0 |' in text
    assert '| pedestrian | - | 0 | 0 | - | 0 | 0 | 75.00 | 4 | 1 |' in text
