"""Pure functions of scripts/lib/dufomap_compare.py (the DUFOMap bench extension, issue 7)."""

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                '..', '..', 'scripts', 'lib'))

import dufomap_compare as dc  # noqa: E402
from multisession_mapper_eval import trajectory as tr  # noqa: E402

XYZ_TIME = [('x', 0, 7, 1), ('y', 4, 7, 1), ('z', 8, 7, 1), ('intensity', 12, 7, 1),
            ('ring', 16, 4, 1), ('time', 20, 7, 1)]


def _cloud_bytes(rows, big_endian=False, pad=0):
    """Bytes of a cloud with the simulator's layout (24-byte points), rows of pad bytes."""
    order = '>' if big_endian else '<'
    dtype = np.dtype({'names': ['x', 'y', 'z', 'intensity', 'ring', 'time'],
                      'formats': [order + 'f4'] * 4 + [order + 'u2', order + 'f4'],
                      'offsets': [0, 4, 8, 12, 16, 20], 'itemsize': 24})
    out = b''
    for row in rows:
        records = np.zeros(len(row), dtype=dtype)
        for i, (x, y, z, t) in enumerate(row):
            records[i] = (x, y, z, 7.0, 3, t)
        out += records.tobytes() + b'\0' * pad
    return out


def _rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _pose(r, t):
    pose = np.eye(4)
    pose[:3, :3] = r
    pose[:3, 3] = t
    return pose


def test_cloud_arrays_reads_xyz_and_time():
    data = _cloud_bytes([[(1, 2, 3, 0.0), (4, 5, 6, 0.05)]])
    cols = dc.cloud_arrays(data, XYZ_TIME, 24, 48, 2, 1, False)
    assert cols['x'].tolist() == [1, 4] and cols['z'].tolist() == [3, 6]
    assert cols['time'] == pytest.approx([0.0, 0.05])
    assert 'intensity' not in cols


def test_cloud_arrays_padded_rows_big_endian_and_numpy_input():
    rows = [[(1, 1, 1, 0.0)], [(2, 2, 2, 0.01)]]
    data = np.frombuffer(_cloud_bytes(rows, big_endian=True, pad=8), dtype=np.uint8)
    cols = dc.cloud_arrays(data, XYZ_TIME, 24, 32, 1, 2, True)
    assert cols['x'].tolist() == [1, 2] and cols['time'] == pytest.approx([0.0, 0.01])


def test_cloud_arrays_without_time():
    fields = XYZ_TIME[:3]
    data = np.zeros(2, dtype='<f4,<f4,<f4').tobytes()
    cols = dc.cloud_arrays(data, fields, 12, 24, 2, 1, False)
    assert set(cols) == {'x', 'y', 'z'}


@pytest.mark.parametrize('fields', [XYZ_TIME[1:], [('x', 0, 8, 1)] + XYZ_TIME[1:]])
def test_cloud_arrays_rejects_other_layouts(fields):
    with pytest.raises(ValueError):
        dc.cloud_arrays(_cloud_bytes([[(1, 2, 3, 0)]]), fields, 24, 24, 1, 1, False)


def test_cloud_arrays_rejects_short_data():
    with pytest.raises(ValueError):
        dc.cloud_arrays(b'\0' * 30, XYZ_TIME, 24, 48, 2, 1, False)


@pytest.mark.parametrize('axis, angle', [((0, 0, 1), 0.3), ((1, 2, -1), 2.0),
                                         ((0, 1, 0), 0.0), ((1, 0, 0), np.pi)])
def test_rotation_log_and_rodrigues_round_trip(axis, angle):
    rotvec = np.asarray(axis, float) / np.linalg.norm(axis) * angle
    vectors = np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1]])
    rotated = dc.rotate_by_rotvecs(np.tile(rotvec, (3, 1)), vectors)
    r = rotated.T  # columns: the images of the basis
    assert np.allclose(r @ r.T, np.eye(3)) and np.linalg.det(r) == pytest.approx(1.0)
    back = dc.rotation_log(r)
    if angle < np.pi:
        assert np.allclose(back, rotvec, atol=1e-9)
    else:  # a half turn: +axis and -axis are the same rotation
        assert np.allclose(np.abs(back), np.abs(rotvec), atol=1e-6)


def test_rotate_by_rotvecs_quarter_turn_about_z():
    out = dc.rotate_by_rotvecs([[0, 0, np.pi / 2]], [[1.0, 0, 0]])
    assert np.allclose(out, [[0, 1, 0]], atol=1e-12)


def test_scan_pose_pair_inside_and_extrapolated():
    poses = [_pose(_rot_z(0.1 * k), [k, 0, 0]) for k in range(3)]
    traj = tr.Trajectory([10.0, 10.1, 10.2], poses)
    p0, p1, dt = dc.scan_pose_pair(traj, 0)
    assert np.allclose(p0, poses[0]) and np.allclose(p1, poses[1]) and dt == pytest.approx(0.1)
    p0, p1, dt = dc.scan_pose_pair(traj, 2)  # last: the previous step repeated
    assert np.allclose(p0, poses[2]) and dt == pytest.approx(0.1)
    assert np.allclose(p1, poses[2] @ tr.inverse(poses[1]) @ poses[2])
    single = tr.Trajectory([5.0], poses[:1])
    p0, p1, dt = dc.scan_pose_pair(single, 0)
    assert np.allclose(p0, p1) and dt > 0


def test_place_points_interpolates_pose_per_point():
    pose0 = _pose(np.eye(3), [0, 0, 0])
    pose1 = _pose(_rot_z(0.2), [1.0, 0, 0])
    points = np.array([[1.0, 0, 0]] * 3)
    times = np.array([0.0, 0.05, 0.1])
    placed = dc.place_points(points, times, pose0, pose1, 0.1)
    assert np.allclose(placed[0], [1, 0, 0])
    assert np.allclose(placed[1], _rot_z(0.1) @ [1, 0, 0] + [0.5, 0, 0])
    assert np.allclose(placed[2], tr.transform_points(pose1, points[2:]))
    # Without times (or without motion) every point takes the stamp pose.
    assert np.allclose(dc.place_points(points, None, pose1, pose0, 0.1),
                       tr.transform_points(pose1, points))
    assert np.allclose(dc.place_points(points, times, pose1, pose1, 0.1),
                       tr.transform_points(pose1, points))


def test_dufomap_pose_order_is_xyz_wxyz():
    pose = _pose(_rot_z(np.pi / 2), [1, 2, 3])
    x, y, z, qw, qx, qy, qz = dc.dufomap_pose(pose)
    assert (x, y, z) == (1, 2, 3)
    assert qw == pytest.approx(np.sqrt(0.5)) and qz == pytest.approx(np.sqrt(0.5))
    assert qx == pytest.approx(0) and qy == pytest.approx(0)


def test_markdown_table_rows_and_missing_values():
    figures = {'static': {'sa': 0.5}, 'low': {'da': None}, 'high': {'da': 0.884},
               'canopy': {'sa': 1.0}, 'points': {'map': 12}}
    row = dc.table_row('X', 'truth', figures, 1.3, None)
    text = dc.markdown_table([row])
    lines = text.splitlines()
    assert len(lines) == 3 and lines[0].startswith('| method |')
    assert lines[2] == '| X | truth | 50.0 | - | 88.4 | 100.0 | 12 | 1.3 | - |'


def test_point_keys_find_float32_copies_and_tell_points_apart():
    cloud = np.array([[1.2341, -200.5, 3.0], [1.2361, -200.5, 3.0], [-999.0, 0.0, 999.0]],
                     dtype=np.float32)
    static = cloud[[2, 0]].copy()
    kept = np.isin(dc.point_keys(cloud), dc.point_keys(static))
    assert kept.tolist() == [True, False, True]
    with pytest.raises(ValueError):
        dc.point_keys(np.array([[1100.0, 0.0, 0.0]]))


def test_voxel_centroids_one_mean_per_occupied_voxel():
    points = np.array([[0.05, 0.05, 0.0], [0.15, 0.05, 0.0], [0.25, 0.0, 0.0], [-0.1, 0, 0]])
    centroids = dc.voxel_centroids(points, 0.2)
    got = sorted(map(tuple, np.round(centroids, 6)))
    assert got == [(-0.1, 0.0, 0.0), (0.1, 0.05, 0.0), (0.25, 0.0, 0.0)]
    assert dc.voxel_centroids(np.zeros((0, 3)), 0.2).shape == (0, 3)


def test_per_point_figures_count_kept_static_and_removed_dynamic():
    s, lo, hi = dc.dynamics.STATIC, dc.dynamics.LOW, dc.dynamics.HIGH
    canopy = dc.dynamics.CANOPY_CLASS
    category = [s, s, s, s, lo, lo, hi, hi, hi, hi]
    labels = [0, 0, canopy, canopy, 7, 7, 9, 9, 10, 10]
    kept = [1, 1, 1, 0, 0, 1, 0, 0, 0, 1]
    f = dc.per_point_figures(category, labels, kept)
    assert f['static']['sa'] == pytest.approx(0.75)
    assert f['canopy']['sa'] == pytest.approx(0.5)
    assert f['low']['da'] == pytest.approx(0.5)
    assert f['high']['da'] == pytest.approx(0.75)
    assert f['points']['map'] == 5 and f['points']['high'] == 4
    empty = dc.per_point_figures([s], [0], [1])
    assert empty['low']['da'] is None and empty['high']['da'] is None
