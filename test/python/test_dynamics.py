import math

import numpy as np
import pytest

from multisession_mapper_eval import dynamics
from multisession_mapper_eval import io
from multisession_mapper_eval import trajectory as tr

import synthetic_case

E = synthetic_case.EXPECTED['dynamics']


def _line(y, n=50):
    return tr.Trajectory(np.arange(n, dtype=float), [np.eye(4) + np.pad(
        np.array([[0, 0, 0, i], [0, 0, 0, y], [0, 0, 0, 0]], float), ((0, 1), (0, 0)))
        for i in range(n)])


def test_observed_rule_decides_low_dynamic():
    trajectories = {'a': _line(0.0), 'b': _line(100.0)}
    objects = [{'id': 1, 'class': 'parked_car', 'pose': [10, 5, 0, 0], 'sessions': ['a']},
               {'id': 2, 'class': 'parked_car', 'pose': [10, 95, 0, 0], 'sessions': ['b']},
               {'id': 3, 'class': 'parked_car', 'pose': [10, 5, 0, 0], 'sessions': ['a', 'b']},
               {'id': 4, 'class': 'moving_car', 'pose': [10, 5, 0, 0], 'sessions': ['a']}]
    # 1: b passes 95 m away -> not observed by b -> static. 2: a is 95 m away -> static.
    assert dynamics.low_dynamic_objects(objects, ['a', 'b'], trajectories, 30.0) == set()
    # With a 100 m radius b observes object 1's place without it: low dynamic (also 2).
    assert dynamics.low_dynamic_objects(objects, ['a', 'b'], trajectories, 100.0) == {1, 2}
    # Only the map's sessions count: with a alone, object 1 (present in a) is static.
    assert dynamics.low_dynamic_objects(objects, ['a'], trajectories, 100.0) == {2}


def test_scores_by_hand():
    s = dynamics.scores(0.9, 0.4)
    assert s['aa'] == pytest.approx(0.6) and s['ha'] == pytest.approx(0.72 / 1.3)
    assert dynamics.scores(None, 0.5)['aa'] is None


def test_known_kept_and_removed_points():
    rng = np.random.default_rng(5)
    static = rng.uniform(0, 10, (1000, 3)).round(1) * 5        # spacing >= 0.5 m
    static = np.unique(static, axis=0)
    dynamic = static[:100] + [0, 0, 100]                       # far above the static ones
    points = np.vstack([static, dynamic])
    labels = np.r_[np.full(len(static), 1), np.full(100, 9)]
    labels[:50] = 6                                            # canopy
    category = dynamics.classify(labels, np.zeros(len(points), int), set())
    assert np.sum(category == dynamics.HIGH) == 100
    kept_static = static[10:]          # 10 canopy points lost
    kept_dynamic = dynamic[:30]        # 70 of 100 removed
    map_points = np.vstack([kept_static, kept_dynamic]) + 0.05
    figures, kept = dynamics.evaluate(points, labels, category, map_points, 0.2)
    n = len(static)
    assert figures['static']['sa'] == pytest.approx((n - 10) / n)
    assert figures['canopy']['sa'] == pytest.approx(40 / 50)
    assert figures['high']['da'] == pytest.approx(0.7)
    assert figures['low']['da'] is None
    assert kept.sum() == n - 10 + 30


def _synthetic_inputs(synthetic_dirs):
    """(map_dir, truth, names, truth trajectories, T_map_world) of the synthetic case."""
    map_dir, truth = io.MapDir(synthetic_dirs[0]), io.Truth(synthetic_dirs[1])
    names = {n: n for n in map_dir.session_names}
    trajectories = {n: truth.trajectory(n) for n in names}
    return map_dir, truth, names, trajectories, tr.inverse(trajectories['s00'].poses[0])


def _active_map_points(map_dir):
    return np.vstack([s.load_points() for s in map_dir.submaps if s.status == 'active'])


def test_synthetic_case_figures(synthetic_dirs):
    map_dir, truth, names, trajectories, t_map_world = _synthetic_inputs(synthetic_dirs)
    gt = dynamics.ground_truth(truth, map_dir.session_names, names, trajectories, t_map_world,
                               30.0, 0.1, 60.0)
    points, labels, ids, category = gt.points, gt.labels, gt.object_ids, gt.category
    assert gt.excluded == 0
    assert len(gt.all_points) == 129 + 139  # both sessions' clouds before de-duplication
    radius_rule = dynamics.ground_truth(truth, map_dir.session_names, names, trajectories,
                                        t_map_world, 30.0, 0.1, 60.0, observed_rule='radius')
    np.testing.assert_array_equal(radius_rule.category, gt.category)
    assert np.sum(category == dynamics.STATIC) == E['static_points']
    assert np.sum(category == dynamics.LOW) == E['low_points']
    assert set(ids[category == dynamics.LOW].tolist()) == {17}
    map_points = _active_map_points(map_dir)
    figures, _ = dynamics.evaluate(points, labels, category, map_points, 0.2)
    assert figures['static']['sa'] == pytest.approx(E['static_sa'])
    assert figures['canopy']['sa'] == pytest.approx(E['canopy_sa'])
    assert figures['low']['da'] == pytest.approx(E['low_da'])
    assert figures['high']['da'] == pytest.approx(E['high_da'])
    assert figures['low']['aa'] == pytest.approx(E['low_aa'])
    assert figures['low']['ha'] == pytest.approx(E['low_ha'])
    assert math.isclose(figures['all_dynamic']['da'], 14 / 17)


def test_deduplicate_one_point_per_voxel_and_object():
    points = np.array([[0.01, 0.01, 0.01], [0.02, 0.05, 0.09], [0.02, 0.05, 0.09],
                       [0.15, 0.0, 0.0], [-0.05, 0.0, 0.0]])
    ids = np.array([1, 1, 2, 1, 1])
    # voxel (0,0,0): ids 1 and 2 -> 2 points; voxel (1,0,0) and (-1,0,0): 1 each.
    assert dynamics.deduplicate(points, ids, 0.1).tolist() == [0, 2, 3, 4]
    assert len(dynamics.deduplicate(points, ids, 0.0)) == 5


def test_evaluation_range_excludes_far_points(synthetic_dirs):
    map_dir, truth, names, trajectories, t_map_world = _synthetic_inputs(synthetic_dirs)
    # Within 5 m of a scan position: only the moving car (3.1 m) and pedestrian (3.2-4.6 m);
    # wall (8 m), canopy, parked cars (5.06 m) and the far car are excluded.
    gt = dynamics.ground_truth(truth, map_dir.session_names, names, trajectories, t_map_world,
                               30.0, 0.1, 5.0)
    assert gt.excluded == E['static_points'] + E['low_points']
    assert np.sum(gt.category == dynamics.HIGH) == E['high_points'] and len(gt.category) == 9


def test_same_category_rule_ignores_the_road_below_a_removed_car():
    # Road GT points on a 0.5 m grid at z = 0; a moving car's lowest GT points 0.15 m above.
    road = np.array([[x, y, 0.0] for x in np.arange(0, 5, 0.5) for y in np.arange(0, 3, 0.5)])
    car = road[:20] + [0, 0, 0.15]
    points = np.vstack([road, car])
    labels = np.r_[np.zeros(len(road), int), np.full(len(car), 9)]
    category = dynamics.classify(labels, np.zeros(len(points), int), set())
    cleaned = road + [0.01, 0.0, 0.02]         # a perfect map: the road only
    figures, _ = dynamics.evaluate(points, labels, category, cleaned, 0.2)
    assert figures['static']['sa'] == 1.0 and figures['high']['da'] == 1.0
    naive, _ = dynamics.evaluate(points, labels, category, cleaned, 0.2, rule='any')
    assert naive['high']['da'] == 0.0          # the naive rule blames the road
    kept_car = np.vstack([cleaned, car[:5]])   # 5 car points left in the map
    figures, _ = dynamics.evaluate(points, labels, category, kept_car, 0.2)
    assert figures['high']['da'] == pytest.approx(15 / 20) and figures['static']['sa'] == 1.0


def test_footprint_rule():
    # A car (4.5 x 1.8 x 1.5 m) centred at (10, 5, 0.75), long axis along y (yaw 90 deg).
    car = {'id': 1, 'class': 'parked_car', 'pose': [10, 5, 0.75, math.pi / 2],
           'size': [4.5, 1.8, 1.5], 'sessions': ['a']}
    along_y = np.array([[10.0, 5 + d, 0.0] for d in np.linspace(-2.0, 2.0, 9)])
    along_x = np.array([[10 + d, 5.0, 0.0] for d in np.linspace(-2.0, 2.0, 9)])
    pts = along_y[np.argsort(along_y[:, 0], kind='stable')]
    assert dynamics.footprint_points(pts, car, 0.0) == 9
    pts = along_x[np.argsort(along_x[:, 0], kind='stable')]
    assert dynamics.footprint_points(pts, car, 0.0) == 3    # |dx| <= 0.9 only
    assert dynamics.footprint_points(pts, car, 0.6) == 7    # |dx| <= 1.5
    # Session b saw the ground under the car without it: low dynamic. c saw nothing there.
    assert dynamics.low_dynamic_by_footprint([car], ['a', 'b'], {'b': along_y}) == {1}
    assert dynamics.low_dynamic_by_footprint([car], ['a', 'c'], {'c': along_y + 50}) == set()
    assert dynamics.low_dynamic_by_footprint([car], ['a', 'b'], {'b': along_y},
                                             min_points=10) == set()


def test_footprint_rule_respects_the_mapping_range():
    car = {'id': 1, 'class': 'parked_car', 'pose': [10, 5, 0.75, 0.0],
           'size': [4.5, 1.8, 1.5], 'sessions': ['a']}
    ground = np.array([[10 + d, 5.0, 0.0] for d in np.linspace(-2.0, 2.0, 9)])
    far = {'b': _line(100.0)}   # session b drove 95 m away: beyond a 60 m mapping range
    assert dynamics.low_dynamic_by_footprint([car], ['a', 'b'], {'b': ground}, 0.3, 5,
                                             far, 60.0) == set()
    assert dynamics.low_dynamic_by_footprint([car], ['a', 'b'], {'b': ground}, 0.3, 5,
                                             far, 100.0) == {1}


class _TruthWithRanges(object):
    """Truth of one session whose labels carry the simulator's `range` field."""

    def __init__(self, points, labels, ids, ranges):
        self._labels = (points, labels, ids, ranges)
        self.objects = []

    def labels(self, name):
        return self._labels


def test_points_measured_only_beyond_the_range_limit_are_excluded():
    # Three wall points next to the trajectory: one seen from 20 m, one only from 75 m, one of
    # unknown range (0: kept). All within 60 m of a scan position, so only the range field
    # can tell that the pipeline (range limit 60 m) could never have mapped the second.
    points = np.array([[10.0, 0.0, 1.0], [10.0, 5.0, 1.0], [10.0, 10.0, 1.0]])
    truth = _TruthWithRanges(points, np.full(3, 2), np.full(3, 5), np.array([20.0, 75.0, 0.0]))
    trajectory = tr.Trajectory(np.array([0.0, 1.0]), np.stack([np.eye(4), np.eye(4)]))
    gt = dynamics.ground_truth(truth, ['s00'], {'s00': 's00'}, {'s00': trajectory}, np.eye(4),
                               30.0, 0.1, 60.0)
    assert gt.excluded == 1
    np.testing.assert_allclose(gt.points, points[[0, 2]])
    assert len(gt.all_points) == 3  # labels still transfer from every point
    without_limit = dynamics.ground_truth(truth, ['s00'], {'s00': 's00'}, {'s00': trajectory},
                                          np.eye(4), 30.0, 0.1, 0.0)
    assert without_limit.excluded == 0 and len(without_limit.points) == 3


def test_breakdown_by_range_and_presence():
    # Six points: static at 5 m (kept) and 25 m (lost), low-dynamic of object 7 (present in s00
    # only) at 5 m (removed) and 15 m (kept), of object 8 (s00 + s01) at 45 m (removed), one
    # high-dynamic point at 35 m (removed).
    category = np.array([dynamics.STATIC, dynamics.STATIC, dynamics.LOW, dynamics.LOW,
                         dynamics.LOW, dynamics.HIGH])
    kept = np.array([True, False, False, True, False, False])
    distance = np.array([5.0, 25.0, 5.0, 15.0, 45.0, 35.0])
    ids = np.array([1, 2, 7, 7, 8, 9])
    b = dynamics.breakdown(category, kept, distance, ids, {7: ('s00',), 8: ('s00', 's01')},
                           bands=(0.0, 10.0, 20.0, 40.0))
    r = b['by_range']
    assert [x['from_m'] for x in r] == [0.0, 10.0, 20.0, 40.0] and r[-1]['to_m'] is None
    assert r[0]['sa'] == 1.0 and r[0]['low_da'] == 1.0 and r[0]['high_da'] is None
    assert r[1]['sa'] is None and r[1]['low_da'] == 0.0 and r[1]['low_points'] == 1
    assert r[2]['sa'] == 0.0 and r[2]['high_da'] == 1.0
    assert r[3]['low_da'] == 1.0 and r[3]['static_points'] == 0
    p = b['low_by_presence']
    assert [x['present_in'] for x in p] == [['s00'], ['s00', 's01']]
    assert p[0]['points'] == 2 and p[0]['da'] == 0.5 and p[1]['da'] == 1.0
    assert b['by_class'] == []  # no labels given


def test_breakdown_by_class():
    # Static terrain (kept, lost, kept), a static wall point (lost), a static parked car (kept),
    # a low-dynamic parked car (kept, i.e. not removed) and two pedestrian points (one removed).
    category = np.array([dynamics.STATIC] * 5 + [dynamics.LOW] + [dynamics.HIGH] * 2)
    labels = np.array([0, 0, 2, 0, 7, 7, 10, 10])
    kept = np.array([True, False, False, True, True, True, False, True])
    b = dynamics.breakdown(category, kept, np.full(8, 5.0), np.arange(8), {}, labels=labels)
    rows = {r['name']: r for r in b['by_class']}
    assert [r['class'] for r in b['by_class']] == [0, 2, 7, 10]
    assert rows['terrain']['static_points'] == 3 and rows['terrain']['static_kept'] == 2
    assert rows['terrain']['sa'] == pytest.approx(2 / 3) and rows['terrain']['low_da'] is None
    assert rows['wall']['sa'] == 0.0
    car = rows['parked car']
    assert (car['static_points'], car['static_kept'], car['low_points'], car['low_removed']) == \
        (1, 1, 1, 0)
    assert car['sa'] == 1.0 and car['low_da'] == 0.0 and car['high_da'] is None
    walker = rows['pedestrian']
    assert walker['high_points'] == 2 and walker['high_removed'] == 1
    assert walker['high_da'] == 0.5 and walker['sa'] is None


def test_ground_truth_gives_path_distances_and_presence(synthetic_dirs):
    map_dir, truth, names, trajectories, t_map_world = _synthetic_inputs(synthetic_dirs)
    gt = dynamics.ground_truth(truth, map_dir.session_names, names, trajectories, t_map_world,
                               30.0, 0.1, 60.0)
    positions = tr.transform_points(t_map_world,
                                    np.vstack([t.positions for t in trajectories.values()]))
    expected = np.min(np.linalg.norm(gt.points[:, None, :] - positions[None], axis=2), axis=1)
    np.testing.assert_allclose(gt.path_distance, expected, atol=1e-9)
    assert gt.low_presence == {17: ('s00',)}  # car 17: in s00 only, s01 saw its place empty
    map_points = _active_map_points(map_dir)
    figures, kept = dynamics.evaluate(gt.points, gt.labels, gt.category, map_points, 0.2)
    b = dynamics.breakdown(gt.category, kept, gt.path_distance, gt.object_ids, gt.low_presence)
    assert sum(r['low_points'] for r in b['by_range']) == E['low_points']
    assert sum(r['static_points'] for r in b['by_range']) == E['static_points']
    assert b['low_by_presence'][0]['da'] == pytest.approx(E['low_da'])


def test_breakdown_without_trajectories_has_no_range_bands():
    category = np.array([dynamics.STATIC, dynamics.LOW])
    b = dynamics.breakdown(category, np.array([True, False]), np.full(2, np.inf),
                           np.array([1, 2]), {2: ('s00',)})
    assert b['by_range'] == []
    assert b['low_by_presence'] == [{'present_in': ['s00'], 'objects': 1, 'points': 1,
                                     'da': 1.0}]
