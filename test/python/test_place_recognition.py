import numpy as np
import pytest

from multisession_mapper_eval import io
from multisession_mapper_eval import place_recognition as pr

import synthetic_case

E = synthetic_case.EXPECTED


def test_toy_pr_curve_by_hand():
    # Sorted by distance: T T F T F T, 5 revisits (hand-computed in synthetic_case.py).
    distances = [0.6, 0.1, 0.25, 0.2, 0.4, 0.3]
    correct = [True, True, False, True, False, True]
    thresholds, precision, recall = pr.pr_curve(distances, correct, 5)
    np.testing.assert_allclose(thresholds, [0.1, 0.2, 0.25, 0.3, 0.4, 0.6])
    np.testing.assert_allclose(precision, [1, 1, 2 / 3, 3 / 4, 3 / 5, 4 / 6])
    np.testing.assert_allclose(recall, [0.2, 0.4, 0.4, 0.6, 0.6, 0.8])
    s = pr.summarize_curve(precision, recall)
    assert s['f1max'] == pytest.approx(8 / 11)
    assert s['max_recall_at_full_precision'] == pytest.approx(0.4)


def test_ties_are_one_threshold():
    thresholds, precision, recall = pr.pr_curve([0.5, 0.5, 0.7], [True, False, True], 2)
    np.testing.assert_allclose(thresholds, [0.5, 0.7])
    np.testing.assert_allclose(precision, [0.5, 2 / 3])
    assert pr.summarize_curve(precision, recall)['max_recall_at_full_precision'] == 0.0


def test_session_figures_from_csv(synthetic_dirs):
    map_dir, truth_dir = io.MapDir(synthetic_dirs[0]), io.Truth(synthetic_dirs[1])
    rows = map_dir.place_recognition('s01')
    result = pr.evaluate_session(rows, truth_dir.trajectory('s01'),
                                 {'s00': truth_dir.trajectory('s00')}, radius_m=5.0)
    for key in ('f1max', 'recall_at_1', 'recall_at_5', 'max_recall_at_full_precision',
                'precision_at_threshold', 'recall_at_threshold'):
        assert result[key] == pytest.approx(E[key]), key
    assert result['revisits'] == E['revisits'] and result['queries'] == E['queries']
    # A 1 m radius makes every match (2 m away) wrong.
    strict = pr.evaluate_session(rows, truth_dir.trajectory('s01'),
                                 {'s00': truth_dir.trajectory('s00')}, radius_m=1.0)
    assert strict['revisits'] == 0 and strict['f1max'] is None


def test_no_history_gives_none():
    result = pr.evaluate_session([], None, {})
    assert result['f1max'] is None and result['queries'] == 0
