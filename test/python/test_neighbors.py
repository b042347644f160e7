import numpy as np
import pytest

from multisession_mapper_eval import neighbors


def test_radius_query_known_case():
    ref = np.array([[0, 0, 0], [10, 0, 0]], dtype=float)
    query = np.array([[0.19, 0, 0], [0.21, 0, 0], [10, 0.1, 0.1], [5, 5, 5]])
    expected = [True, False, True, False]
    assert neighbors.has_neighbor_within(ref, query, 0.2).tolist() == expected
    assert neighbors.has_neighbor_within(ref, query, 0.2, use_scipy=False).tolist() == expected


def test_voxel_fallback_equals_kdtree():
    if neighbors.cKDTree is None:
        pytest.skip('scipy not installed: nothing to compare the fallback with')
    rng = np.random.default_rng(42)
    ref = rng.uniform(-5, 5, (20000, 3))
    query = rng.uniform(-6, 6, (20000, 3))
    a = neighbors.has_neighbor_within(ref, query, 0.15)
    b = neighbors.has_neighbor_within(ref, query, 0.15, use_scipy=False)
    assert 0.05 < a.mean() < 0.95
    np.testing.assert_array_equal(a, b)


def test_empty_inputs_and_min_distances():
    assert neighbors.has_neighbor_within(np.zeros((0, 3)), np.ones((3, 3)), 1.0).tolist() == \
        [False] * 3
    d = neighbors.min_distances(np.array([[0, 0, 0.0]]), np.array([[3, 4, 0.0]]))
    assert d[0] == pytest.approx(5.0)


def test_nearest_within_known_case_and_fallback():
    ref = np.array([[0, 0, 0], [0.3, 0, 0], [5, 5, 5]], dtype=float)
    query = np.array([[0.1, 0, 0], [0.2, 0, 0], [0.6, 0, 0], [5, 5, 5.1]])
    expected = [0, 1, -1, 2]
    assert neighbors.nearest_within(ref, query, 0.25).tolist() == expected
    assert neighbors.nearest_within(ref, query, 0.25, use_scipy=False).tolist() == expected
    if neighbors.cKDTree is None:
        return
    rng = np.random.default_rng(9)
    ref = rng.uniform(-5, 5, (20000, 3))
    query = rng.uniform(-6, 6, (20000, 3))
    a = neighbors.nearest_within(ref, query, 0.2)
    b = neighbors.nearest_within(ref, query, 0.2, use_scipy=False)
    assert 0.05 < np.mean(a >= 0) < 0.95
    np.testing.assert_array_equal(a, b)
