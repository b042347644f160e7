"""A hand-made map directory and simulator truth with known answers (for the evaluator tests).

Map frame: the first scan of s00. World frame: T_WORLD_MAP (translation + 90 deg yaw), so the
evaluator must apply the fixed transform. s00 drives x = 0..55 m (56 scans, y = 0), s01 drives
x = 0..99 m at y = 2 with a constant yaw of 0.2 rad. Submaps hold 20 scans each.

Every figure in EXPECTED is computed by hand in the comments below.
"""

import math
import os

import numpy as np
import yaml

from multisession_mapper_eval import pcd
from multisession_mapper_eval import trajectory as tr


def _pose(x, y, z, yaw):
    p = np.eye(4)
    p[:3, :3] = [[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                 [0, 0, 1]]
    p[:3, 3] = [x, y, z]
    return p


T_WORLD_MAP = _pose(100.0, 50.0, 2.0, math.pi / 2)
S00 = tr.Trajectory(1000.0 + 0.1 * np.arange(56), [_pose(i, 0, 0, 0) for i in range(56)])
S01 = tr.Trajectory(2000.0 + 0.1 * np.arange(100), [_pose(i, 2, 0, 0.2) for i in range(100)])


def _grid(x0, x1, y, z0, z1, step=0.5):
    xs = np.arange(x0, x1 + 1e-9, step)
    zs = np.arange(z0, z1 + 1e-9, step)
    return np.array([[x, y, z] for x in xs for z in zs])


# Ground-truth objects in the map frame: (points, label, object_id).
WALL = _grid(0, 10, 10, 0, 2)                                  # 21 x 5 = 105 static
CANOPY = np.array([[20 + 0.5 * i, 10, 5] for i in range(10)])  # 10 static canopy
CAR17 = np.array([[3 + 0.5 * i, -5, 0.75] for i in range(8)])  # low dynamic (s00 only)
CAR18 = np.array([[10 + 0.5 * i, -5, 0.75] for i in range(6)])  # in both sessions: static
CAR19 = np.array([[140 + 0.5 * i, 2, 0.75] for i in range(3)])  # s01 only, never seen by s00
GROUND17 = np.array([[3.5 + 0.5 * i, -5.5, 0.0] for i in range(6)])  # s01 sees under car 17
MOVING = np.array([[30 + 0.5 * i, -3, 0.7] for i in range(5)])  # high dynamic (moving car)
WALKER = np.array([[40, -3 - 0.5 * i, 1.0] for i in range(4)])  # high dynamic (pedestrian)

# What the final map keeps of each (indices into the arrays above).
KEEP = {'ground17': np.arange(6), 'wall': np.arange(5, 105), 'canopy': np.arange(8),
        'car17': np.arange(2),
        'car18': np.arange(6), 'car19': np.arange(3), 'moving': np.arange(0),
        'walker': np.arange(1)}

TIMING = {
    's00': {'wall_time_s': 2.0, 'bag_duration_s': 5.6, 'peak_rss_mb': 300.0,
            'per_scan_ms': {'deskew_odometry': {'median': 5.0, 'p95': 9.0},
                            'descriptor': {'median': 0.4, 'p95': 0.6},
                            'query': {'median': 0.05, 'p95': 0.09},
                            'submap_building': {'median': 1.0, 'p95': 2.0}},
            'per_submap_s': {'intra_loop': {'median': 0.1, 'p95': 0.3}},
            'per_pair_s': {}, 'merge_s': 1.0},
    's01': {'wall_time_s': 4.0, 'bag_duration_s': 10.0, 'peak_rss_mb': 450.0,
            'per_scan_ms': {'deskew_odometry': {'median': 7.0, 'p95': 9.0},
                            'descriptor': {'median': 0.6, 'p95': 0.8},
                            'query': {'median': 0.07, 'p95': 0.09},
                            'submap_building': {'median': 1.2, 'p95': 2.0}},
            'per_submap_s': {'intra_loop': {'median': 0.2, 'p95': 0.3}},
            'per_pair_s': {'global_registration': {'median': 0.4, 'p95': 0.9},
                           'dynamic_detection': {'median': 0.25, 'p95': 0.4}},
            'merge_s': 3.0},
}

_STATIC_TOTAL = 6 + 105 + 10 + 6 + 3
_STATIC_KEPT = 6 + 100 + 8 + 6 + 3
_SA = _STATIC_KEPT / _STATIC_TOTAL
_DA_LOW = 6 / 8
_DA_HIGH = 8 / 9

EXPECTED = {
    # ATE: s00 estimate = truth + (0.1, 0, 0), s01 = truth + (0, 0.2, 0); aligned: 0.
    'ate_rmse_m': [0.1, 0.2],
    'ate_rmse_aligned_m': [0.0, 0.0],
    # s01: sm0 correct (0.1 m error), sm1 wrong (1 m), sm2 missed (rejected, fully overlapping),
    # sm3 new (5 of 20 scans within 10 m of s00), sm4 wrong (exact pose, no overlap).
    'submaps_total': [3, 5], 'submaps_correct': [0, 1], 'submaps_wrong': [0, 2],
    'submaps_undefined_new': [0, 1], 'submaps_undefined_missed': [0, 1],
    'intra_loops_accepted': [2, 0], 'intra_loops_wrong': [1, 0],
    'intra_loops_correct': [1, 0],
    'inter_loops_accepted': [0, 3], 'inter_loops_correct': [0, 1],
    'proximity_loops_accepted': [0, 1], 'proximity_loops_correct': [0, 1],
    'inter_loop_trans_err_median_m': [None, 0.1],
    'intra_loop_rot_err_median_deg': [2.5, None],
    # PR rows (see PR_ROWS): F1max = 8/11 at d = 0.6; recall@1 4/5, recall@5 5/5, P=1 until
    # recall 2/5; at d_alpha (matched rows) 3 of 4 correct.
    'f1max': 8 / 11, 'recall_at_1': 0.8, 'recall_at_5': 1.0,
    'max_recall_at_full_precision': 0.4, 'precision_at_threshold': 0.75,
    'recall_at_threshold': 0.6, 'revisits': 5, 'queries': 6,
    'dynamics': {'static_sa': _SA, 'canopy_sa': 0.8, 'low_da': _DA_LOW, 'high_da': _DA_HIGH,
                 'low_aa': math.sqrt(_SA * _DA_LOW),
                 'low_ha': 2 * _SA * _DA_LOW / (_SA + _DA_LOW),
                 'static_points': _STATIC_TOTAL, 'low_points': 8, 'high_points': 9},
    # timing: (5.6 + 10) / (2 + 4); median of medians; max RSS.
    'realtime_factor': 2.6, 'odometry_ms_median': 6.0, 'global_registration_s_median': 0.4,
    'dynamic_detection_s_per_pair_median': 0.25, 'merge_s_per_session': [1.0, 3.0],
    'peak_rss_mb': 450.0,
}

# (query scan index of s01, matched s00 scan index, distance, matched flag, top_k s00 indices)
PR_ROWS = [(0, 0, 0.10, 1, [0, 7]), (1, 1, 0.20, 1, [1]), (2, 30, 0.25, 1, [30, 2]),
           (3, 3, 0.30, 1, [3]), (80, 40, 0.40, 0, [40, 41]), (4, 4, 0.60, 0, [4])]


def _write_yaml(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, 'w') as f:
        yaml.safe_dump(data, f, sort_keys=False)


def _labels(path, parts):
    points = np.vstack([p for p, _, _ in parts])
    world = tr.transform_points(T_WORLD_MAP, points)
    labels = np.concatenate([np.full(len(p), lab, np.uint8) for p, lab, _ in parts])
    ids = np.concatenate([np.full(len(p), oid, np.uint32) for p, _, oid in parts])
    pcd.write_pcd(path, {'x': world[:, 0].astype(np.float32), 'y': world[:, 1].astype(np.float32),
                         'z': world[:, 2].astype(np.float32), 'label': labels,
                         'object_id': ids}, data='binary_compressed')


def _cloud(path, points_local):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    pts = np.asarray(points_local, dtype=np.float32).reshape(-1, 3)
    pcd.write_pcd(path, {'x': pts[:, 0], 'y': pts[:, 1], 'z': pts[:, 2]})


def make_truth(root):
    os.makedirs(os.path.join(root, 'truth'), exist_ok=True)
    _write_yaml(os.path.join(root, 'sessions.yaml'), {
        'format': 'multisession_mapper_sim/1', 'profile': 'synthetic', 'seed': 0,
        'label_voxel_m': 0.1,
        'sessions': [{'name': n, 'bag': n + '.bag', 'truth_trajectory': 'truth/%s.tum' % n,
                      'labels': 'truth/%s_labels.pcd' % n, 'scans': len(t),
                      'duration_s': float(t.stamps[-1] - t.stamps[0]),
                      'route_length_m': t.path_length()}
                     for n, t in (('s00', S00), ('s01', S01))]})
    for name, t in (('s00', S00), ('s01', S01)):
        tr.write_tum(os.path.join(root, 'truth', name + '.tum'), t.transformed(T_WORLD_MAP))

    def world_pose(p):
        # Boxes are aligned with the map's x axis: yaw pi/2 in the world frame.
        c = tr.transform_points(T_WORLD_MAP, np.mean(p, axis=0)[None, :])[0]
        return [float(c[0]), float(c[1]), float(c[2]), math.pi / 2]

    objects = [
        {'id': 5, 'class': 'building', 'shape': 'box', 'pose': world_pose(WALL),
         'size': [10, 0.3, 2], 'sessions': ['s00', 's01']},
        {'id': 7, 'class': 'canopy', 'shape': 'ellipsoid', 'pose': world_pose(CANOPY),
         'size': [5, 1, 1], 'sessions': ['s00', 's01']},
        {'id': 17, 'class': 'parked_car', 'shape': 'box', 'pose': world_pose(CAR17),
         'size': [4.5, 1.8, 1.5], 'sessions': ['s00']},
        {'id': 18, 'class': 'parked_car', 'shape': 'box', 'pose': world_pose(CAR18),
         'size': [4.5, 1.8, 1.5], 'sessions': ['s00', 's01']},
        {'id': 19, 'class': 'parked_car', 'shape': 'box', 'pose': world_pose(CAR19),
         'size': [4.5, 1.8, 1.5], 'sessions': ['s01']},
        {'id': 900, 'class': 'moving_car', 'shape': 'box', 'size': [4.4, 1.8, 1.5],
         'sessions': ['s01'], 'trajectory': [[2000.0, 0, 0, 0, 0], [2010.0, 10, 0, 0, 0]]},
        {'id': 901, 'class': 'pedestrian', 'shape': 'cylinder', 'size': [0.5, 0.5, 1.8],
         'sessions': ['s01'], 'trajectory': [[2000.0, 0, 0, 0, 0], [2010.0, 5, 0, 0, 0]]},
    ]
    _write_yaml(os.path.join(root, 'world.yaml'), {'format': 'multisession_mapper_sim/1',
                                                   'sessions': ['s00', 's01'],
                                                   'objects': objects})
    _labels(os.path.join(root, 'truth', 's00_labels.pcd'),
            [(WALL, 1, 5), (CANOPY, 6, 7), (CAR17, 7, 17), (CAR18, 7, 18)])
    _labels(os.path.join(root, 'truth', 's01_labels.pcd'),
            [(GROUND17, 0, 0), (WALL, 1, 5), (CANOPY, 6, 7), (CAR18, 7, 18), (CAR19, 7, 19),
             (MOVING, 9, 900), (WALKER, 10, 901)])


def _submaps(name, t, sizes, status=None):
    out, start = [], 0
    for i, n in enumerate(sizes):
        stamps = t.stamps[start:start + n]
        out.append({'session': name, 'id': i, 'origin': tr.pose_to_list(t.poses[start]),
                    'first_stamp': float(stamps[0]), 'last_stamp': float(stamps[-1]),
                    'scan_stamps': [float(s) for s in stamps], 'points': 1,
                    'file': 'submaps/%s/%d.pcd' % (name, i),
                    'status': (status or {}).get(i, 'active')})
        start += n
    return out


def _loop_row(kind, cur_s, cur_id, hist_s, hist_id, status, pose):
    values = tr.pose_to_list(pose) if pose is not None else [''] * 7
    return [kind, cur_s, str(cur_id), hist_s or '', '' if hist_id is None else str(hist_id),
            status, '0.97', '0.8'] + [str(v) for v in values] + ['']


def make_map(root):
    os.makedirs(root, exist_ok=True)
    sub00 = _submaps('s00', S00, [20, 20, 16])
    sub01 = _submaps('s01', S01, [20, 20, 20, 20, 20], status={4: 'fused'})
    _write_yaml(os.path.join(root, 'manifest.yaml'), {
        'format_version': 1, 'map_frame': 'map',
        'sessions': [{'name': 's00', 'bag': 's00.bag', 'scans': 56, 'duration_s': 5.5},
                     {'name': 's01', 'bag': 's01.bag', 'scans': 100, 'duration_s': 9.9}],
        'submaps': sub00 + sub01,
        'parameters': {'submap_builder': {'voxel_size_m': 0.1, 'max_point_range_m': 60.0},
                       'odometry': {'voxel_size_m': 1.5, 'max_point_range_m': 100.0}}})
    # Final map: the kept GT points in submap s00/0, one far-away point in every other submap.
    # Car 17 is low-dynamic: s01 saw the ground under it (GROUND17) without it. Car 19 is
    # static: s00 never saw its place.
    kept = np.vstack([GROUND17[KEEP['ground17']], WALL[KEEP['wall']], CANOPY[KEEP['canopy']],
                      CAR17[KEEP['car17']],
                      CAR18[KEEP['car18']], CAR19[KEEP['car19']], WALKER[KEEP['walker']]])
    origin0 = tr.pose_from_list(sub00[0]['origin'])
    _cloud(os.path.join(root, 'submaps/s00/0.pcd'),
           tr.transform_points(tr.inverse(origin0), kept))
    for entry in sub00[1:] + sub01:
        _cloud(os.path.join(root, entry['file']), [[0.0, 0.0, -50.0]])
    os.makedirs(os.path.join(root, 'trajectories'), exist_ok=True)
    shift0, shift1 = _pose(0.1, 0, 0, 0), _pose(0, 0.2, 0, 0)
    tr.write_tum(os.path.join(root, 'trajectories/s00.tum'), S00.transformed(shift0))
    tr.write_tum(os.path.join(root, 'trajectories/s01.tum'), S01.transformed(shift1))

    def rel(a, b):
        return tr.inverse(a) @ b

    o00 = [tr.pose_from_list(e['origin']) for e in sub00]
    o01 = [tr.pose_from_list(e['origin']) for e in sub01]
    header = ('kind,current_session,current_submap,history_session,history_submap,status,'
              'vote_proportion,overlap_ratio,tx,ty,tz,qx,qy,qz,qw,reason')
    rows00 = [_loop_row('intra', 's00', 1, 's00', 0, 'accepted', rel(o00[0], o00[1])),
              _loop_row('intra', 's00', 2, 's00', 1, 'accepted',
                        rel(o00[1], o00[2]) @ _pose(0, 0, 0, math.radians(5))),
              _loop_row('intra', 's00', 2, 's00', 0, 'rejected', None)]
    rows01 = [_loop_row('inter', 's01', 0, 's00', 0, 'accepted',
                        rel(o00[0], o01[0]) @ _pose(0.1, 0, 0, 0)),
              _loop_row('inter', 's01', 1, 's00', 1, 'accepted',
                        rel(o00[1], o01[1]) @ _pose(1.0, 0, 0, 0)),
              _loop_row('inter', 's01', 2, 's00', 2, 'rejected', _pose(5, 0, 0, 0)),
              _loop_row('inter_proximity', 's01', 2, 's00', 2, 'accepted', rel(o00[2], o01[2])),
              _loop_row('inter', 's01', 3, None, None, 'undefined', None),
              _loop_row('inter', 's01', 4, 's00', 0, 'accepted', rel(o00[0], o01[4]))]
    os.makedirs(os.path.join(root, 'loops'), exist_ok=True)
    for name, rows in (('s00', rows00), ('s01', rows01)):
        with open(os.path.join(root, 'loops', name + '.csv'), 'w') as f:
            f.write(header + '\n' + ''.join(','.join(r) + '\n' for r in rows))
    os.makedirs(os.path.join(root, 'place_recognition'), exist_ok=True)
    with open(os.path.join(root, 'place_recognition/s01.csv'), 'w') as f:
        f.write('stamp,submap,matched,history_session,history_stamp,distance,top_k\n')
        for q, m, d, matched, top in PR_ROWS:
            top_k = ';'.join('s00:%.9f:%.3f' % (S00.stamps[j], d + 0.01 * k)
                             for k, j in enumerate(top))
            f.write('%.9f,%d,%d,s00,%.9f,%.3f,%s\n' % (S01.stamps[q], q // 20, matched,
                                                       S00.stamps[m], d, top_k))
    os.makedirs(os.path.join(root, 'dynamics'), exist_ok=True)
    removed = np.vstack([CAR17[2:], MOVING])
    _cloud(os.path.join(root, 'dynamics/s01_removed.pcd'), removed)
    os.makedirs(os.path.join(root, 'timing'), exist_ok=True)
    for name, record in TIMING.items():
        _write_yaml(os.path.join(root, 'timing', name + '.yaml'), record)
