"""End to end: scripts/evaluate on the hand-made map and truth, compared with the known answers."""

import json
import os
import subprocess
import sys

import pytest

from multisession_mapper_eval import cli

import synthetic_case

E = synthetic_case.EXPECTED
SCRIPT = os.path.join(os.path.dirname(__file__), '..', '..', 'scripts', 'evaluate')

REQUIRED_SESSION_KEYS = {
    'name', 'scans', 'duration_s', 'ate_rmse_m', 'ate_rmse_aligned_m', 'rpe_100m_pct',
    'rpe_100m_deg', 'submaps_total', 'submaps_correct', 'submaps_wrong',
    'submaps_undefined_new', 'submaps_undefined_missed', 'intra_loops_accepted',
    'intra_loops_wrong', 'place_recognition'}


@pytest.fixture(scope='module')
def report(synthetic_dirs, tmp_path_factory):
    out = str(tmp_path_factory.mktemp('report'))
    env = dict(os.environ, PYTHONPATH='')  # the script must find the package by itself
    # The hand-made answers are in the first scan's frame (the map-fit frame: see
    # test_map_fit_frame_ignores_the_first_scan_pose).
    proc = subprocess.run([sys.executable, SCRIPT, '--map', synthetic_dirs[0],
                           '--truth', synthetic_dirs[1], '--out', out,
                           '--dynamics-frame', 'first-scan'],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env,
                          universal_newlines=True, check=False)
    assert proc.returncode == 0, proc.stderr
    with open(os.path.join(out, 'report.json')) as f:
        text = f.read()
    return json.loads(text), out, proc.stdout


def test_required_keys_present(report):
    data, _, _ = report
    assert [s['name'] for s in data['sessions']] == ['s00', 's01']
    for s in data['sessions']:
        assert REQUIRED_SESSION_KEYS <= set(s)
        assert {'f1max', 'recall_at_1', 'recall_at_5',
                'max_recall_at_full_precision'} <= set(s['place_recognition'])
    assert set(data['dynamics']['low']) >= {'sa', 'da', 'aa', 'ha'}
    assert 'da' in data['dynamics']['high'] and 'sa' in data['dynamics']['static']
    assert 'sa' in data['dynamics']['canopy']
    assert {'points_total', 'bytes_on_disk', 'bytes_on_disk_per_session'} <= set(data['map'])
    assert {'realtime_factor', 'odometry_ms_median', 'descriptor_ms_median', 'query_ms_median',
            'global_registration_s_median', 'dynamic_detection_s_per_pair_median',
            'merge_s_per_session', 'peak_rss_mb'} <= set(data['timing'])


def test_values_equal_the_known_answers(report):
    data, _, _ = report
    s = data['sessions']
    assert [x['scans'] for x in s] == [56, 100]
    for key in ('ate_rmse_m', 'ate_rmse_aligned_m'):
        assert [x[key] for x in s] == pytest.approx(E[key], abs=1e-6), key
    for key in ('submaps_total', 'submaps_correct', 'submaps_wrong', 'submaps_undefined_new',
                'submaps_undefined_missed', 'intra_loops_accepted', 'intra_loops_wrong'):
        assert [x[key] for x in s] == E[key], key
    assert s[0]['place_recognition']['f1max'] is None
    p = s[1]['place_recognition']
    for key in ('f1max', 'recall_at_1', 'recall_at_5', 'max_recall_at_full_precision'):
        assert p[key] == pytest.approx(E[key]), key
    assert s[0]['rpe_10m_pct'] == pytest.approx(0.0, abs=1e-6)
    assert s[0]['rpe_100m_pct'] is None and s[0]['rpe_100m_pairs'] == 0  # 55 m route
    d = data['dynamics']
    assert d['static']['sa'] == pytest.approx(E['dynamics']['static_sa'])
    assert d['canopy']['sa'] == pytest.approx(E['dynamics']['canopy_sa'])
    assert d['low']['da'] == pytest.approx(E['dynamics']['low_da'])
    assert d['low']['aa'] == pytest.approx(E['dynamics']['low_aa'])
    assert d['low']['ha'] == pytest.approx(E['dynamics']['low_ha'])
    assert d['high']['da'] == pytest.approx(E['dynamics']['high_da'])
    assert data['map']['points_total'] == 132
    assert data['map']['bytes_after_session'] == [None, None]  # not recorded by this map
    assert [x['submaps_unknown'] for x in s] == [0, 0]
    t = data['timing']
    for key in ('realtime_factor', 'odometry_ms_median', 'global_registration_s_median',
                'dynamic_detection_s_per_pair_median', 'peak_rss_mb'):
        assert t[key] == pytest.approx(E[key]), key
    assert t['merge_s_per_session'] == E['merge_s_per_session']


def test_fractions_in_unit_interval(report):
    data, _, _ = report

    def walk(value, key=''):
        if isinstance(value, dict):
            for k, v in value.items():
                walk(v, k)
        elif isinstance(value, list):
            for v in value:
                walk(v, key)
        elif key in ('sa', 'da', 'aa', 'ha', 'f1max', 'recall_at_1', 'recall_at_5',
                     'max_recall_at_full_precision') and value is not None:
            assert 0.0 <= value <= 1.0, key
    walk(data)


def test_outputs_and_printed_tables(report):
    data, out, stdout = report
    for name in ('report.md', 'map_top.png', 'trajectories.png', 'place_recognition_pr.png',
                 'loop_table.png'):
        assert os.path.isfile(os.path.join(out, name)), name
    assert sorted(data['plots']) == ['loop_table.png', 'map_top.png',
                                     'place_recognition_pr.png', 'trajectories.png']
    assert 'Inter-session loop closure' in stdout and '| s01 | 5 | 1 | 0 | 1 | 1 | 2 |' in stdout
    assert data['warnings'] == ['s00: no timing/s00.yaml'] or data['warnings'] == []


def test_missing_inputs_fail_clearly(tmp_path, capsys):
    assert cli.main(['--map', str(tmp_path), '--truth', str(tmp_path), '--quiet']) == 2
    assert 'manifest.yaml' in capsys.readouterr().err


def test_partial_map_still_evaluates(synthetic_dirs, tmp_path):
    # Without loops, place recognition, timing and labels the report is still written.
    import shutil
    map_copy, truth_copy = str(tmp_path / 'map'), str(tmp_path / 'sim')
    shutil.copytree(synthetic_dirs[0], map_copy)
    shutil.copytree(synthetic_dirs[1], truth_copy)
    for folder in ('loops', 'place_recognition', 'timing'):
        shutil.rmtree(os.path.join(map_copy, folder))
    os.remove(os.path.join(truth_copy, 'truth', 's00_labels.pcd'))
    os.remove(os.path.join(truth_copy, 'truth', 's01_labels.pcd'))
    out = str(tmp_path / 'out')
    assert cli.main(['--map', map_copy, '--truth', truth_copy, '--out', out, '--quiet',
                     '--no-plots']) == 0
    with open(os.path.join(out, 'report.json')) as f:
        data = json.load(f)
    # No loops at all: submaps 0, 1, 2 overlap s00 (missed), 3 and 4 do not (new).
    assert data['sessions'][1]['submaps_undefined_missed'] == 3
    assert data['sessions'][1]['submaps_undefined_new'] == 2
    assert data['dynamics']['evaluated'] is False and data['timing']['realtime_factor'] is None
    assert any('loops/s01.csv' in w for w in data['warnings'])


def test_parameters_from_the_manifest(report):
    data, _, _ = report
    assert data['dynamics']['kept_radius_m'] == 0.2      # max(0.2, submap voxel 0.1)
    assert data['dynamics']['eval_range_m'] == 60.0      # the submap builder's, not odometry's
    params = {'odometry': {'voxel_size_m': 1.5}, 'submap_builder': {'voxel_size_m': 0.25}}
    assert cli.find_parameter(params, 'voxel_size_m') == 0.25
    assert cli.find_parameter({'a': {'voxel_size_m': 0.3}}, 'voxel_size_m') == 0.3
    assert cli.find_parameter({'a': {'x': 1.0}, 'b': {'x': 2.0}}, 'x') is None


def test_truth_in_map_frame_is_written(report):
    from multisession_mapper_eval import trajectory as tr
    _, out, _ = report
    t = tr.read_tum(os.path.join(out, 'truth_map_frame', 's01.tum'))
    assert len(t) == 100
    assert abs(t.positions[5][0] - 5.0) < 1e-6 and abs(t.positions[5][1] - 2.0) < 1e-6


def _copy_of_map(synthetic_dirs, tmp_path, name):
    """A copy of the synthetic map: (its directory, its manifest, the submap entries by key)."""
    import shutil
    import yaml
    copy = str(tmp_path / name)
    shutil.copytree(synthetic_dirs[0], copy)
    with open(os.path.join(copy, 'manifest.yaml')) as f:
        manifest = yaml.safe_load(f)
    return copy, manifest, {(s['session'], s['id']): s for s in manifest['submaps']}


def _write_manifest(map_dir, manifest):
    import yaml
    with open(os.path.join(map_dir, 'manifest.yaml'), 'w') as f:
        yaml.safe_dump(manifest, f, sort_keys=False)


def _report_of(map_dir, truth_dir, out, *extra):
    assert cli.main(['--map', map_dir, '--truth', truth_dir, '--out', out, '--quiet',
                     '--no-plots', '--dynamics-frame', 'first-scan'] + list(extra)) == 0
    with open(os.path.join(out, 'report.json')) as f:
        return json.load(f)


def test_submap_origins_truth_measures_the_content_without_the_alignment(synthetic_dirs,
                                                                         tmp_path):
    # The synthetic submaps sit at their true origins, and all points are in s00/0. A copy moves
    # those points into s00/1 (same place in the map) and then moves that submap's origin by
    # 3 m. (s00/0 cannot be moved: its origin anchors the map frame.) Placed at the estimated
    # origins the copy loses static points; placed at the true origins (the diagnosis) it scores
    # what the unmodified map scores.
    import numpy as np
    from multisession_mapper_eval import pcd
    from multisession_mapper_eval import trajectory as tr
    shifted, manifest, entries = _copy_of_map(synthetic_dirs, tmp_path, 'shifted')
    o0 = tr.pose_from_list(entries[('s00', 0)]['origin'])
    o1 = tr.pose_from_list(entries[('s00', 1)]['origin'])
    points = pcd.xyz(pcd.read_pcd(os.path.join(shifted, 'submaps/s00/0.pcd')))
    moved = tr.transform_points(tr.inverse(o1) @ o0, points).astype(np.float32)
    pcd.write_pcd(os.path.join(shifted, 'submaps/s00/1.pcd'),
                  {'x': moved[:, 0], 'y': moved[:, 1], 'z': moved[:, 2]})
    far = np.array([0.0], np.float32)
    pcd.write_pcd(os.path.join(shifted, 'submaps/s00/0.pcd'),
                  {'x': far, 'y': far, 'z': far - 50.0})
    entries[('s00', 1)]['origin'][0] += 3.0
    _write_manifest(shifted, manifest)

    def dynamics_of(map_dir, origins):
        out = str(tmp_path / ('out_%s_%s' % (os.path.basename(map_dir), origins)))
        return _report_of(map_dir, synthetic_dirs[1], out, '--submap-origins',
                          origins)['dynamics']

    original = dynamics_of(synthetic_dirs[0], 'estimated')
    assert dynamics_of(synthetic_dirs[0], 'truth')['static'] == original['static']
    assert dynamics_of(shifted, 'estimated')['static']['sa'] < original['static']['sa']
    truth_origins = dynamics_of(shifted, 'truth')
    assert truth_origins['submap_origins'] == 'truth'
    assert truth_origins['static'] == original['static']
    assert truth_origins['low'] == original['low'] and truth_origins['high'] == original['high']


def test_a_reanchored_first_submap_keeps_the_map_frame_of_the_first_scan(synthetic_dirs,
                                                                         tmp_path):
    # The frame anchor (frame_anchor.h) moves submap s00/0's origin off the identity and records
    # the first scan's pose in that submap instead, so that the first scan stays the identity.
    # The same map content expressed that way must score exactly what the original scores: the
    # map frame is the first scan's, not submap 0's origin.
    import numpy as np
    from multisession_mapper_eval import pcd
    from multisession_mapper_eval import trajectory as tr
    anchored, manifest, entries = _copy_of_map(synthetic_dirs, tmp_path, 'anchored')
    entry = entries[('s00', 0)]
    origin = tr.pose_from_list(entry['origin'])
    yaw, offset = 0.05, np.array([0.4, -0.3, 0.1])
    b = np.eye(4)
    b[:3, :3] = [[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0, 0, 1]]
    b[:3, 3] = offset
    new_origin = origin @ b
    entry['origin'] = tr.pose_to_list(new_origin)
    entry['scan_poses'] = [tr.pose_to_list(tr.inverse(b))]
    cloud = os.path.join(anchored, 'submaps/s00/0.pcd')
    points = tr.transform_points(tr.inverse(b), pcd.xyz(pcd.read_pcd(cloud))).astype(np.float32)
    pcd.write_pcd(cloud, {'x': points[:, 0], 'y': points[:, 1], 'z': points[:, 2]})
    _write_manifest(anchored, manifest)
    # Loops into s00/0 hold poses relative to its frame, which moved by b.
    for name in ('s00', 's01'):
        csv_path = os.path.join(anchored, 'loops', name + '.csv')
        with open(csv_path) as f:
            lines = f.read().splitlines()
        head = lines[0].split(',')
        cols = [head.index(k) for k in ('tx', 'ty', 'tz', 'qx', 'qy', 'qz', 'qw')]
        for i in range(1, len(lines)):
            row = lines[i].split(',')
            into_first = (row[head.index('history_session')] == 's00'
                          and row[head.index('history_submap')] == '0')
            if into_first and row[cols[0]]:
                pose = tr.inverse(b) @ tr.pose_from_list([float(row[c]) for c in cols])
                for c, v in zip(cols, tr.pose_to_list(pose)):
                    row[c] = repr(float(v))
                lines[i] = ','.join(row)
        with open(csv_path, 'w') as f:
            f.write('\n'.join(lines) + '\n')

    original = _report_of(synthetic_dirs[0], synthetic_dirs[1], str(tmp_path / 'out_original'))
    moved = _report_of(anchored, synthetic_dirs[1], str(tmp_path / 'out_anchored'))
    assert moved['dynamics']['static']['sa'] == pytest.approx(original['dynamics']['static']['sa'])
    assert moved['dynamics']['low'] == pytest.approx(original['dynamics']['low'])
    for a, b2 in zip(original['sessions'], moved['sessions']):
        assert b2['ate_rmse_m'] == pytest.approx(a['ate_rmse_m'], abs=1e-9)
        assert b2['submaps_correct'] == a['submaps_correct']
        assert b2['submaps_wrong'] == a['submaps_wrong']


def test_map_fit_frame_ignores_the_first_scan_pose(synthetic_dirs, tmp_path):
    # A copy whose first scan sits 0.05 rad / 0.3 m off in its submap (the rest of the map, the
    # trajectories and the points unchanged): in the first scan's frame the whole map is then
    # turned against the truth, so the ATE grows and static points are lost; the map-fit frame
    # (one SE(3) fit of all sessions' poses) is the same as for the original map, and so are
    # its ATE and its dynamics figures.
    import numpy as np
    from multisession_mapper_eval import trajectory as tr
    turned, manifest, entries = _copy_of_map(synthetic_dirs, tmp_path, 'turned')
    yaw = 0.05
    b = np.eye(4)
    b[:3, :3] = [[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0, 0, 1]]
    b[:3, 3] = [0.3, 0.0, 0.0]
    entry = entries[('s00', 0)]
    assert 'scan_poses' not in entry  # the identity
    entry['scan_poses'] = [tr.pose_to_list(b)]
    _write_manifest(turned, manifest)

    def report_of(map_dir, frame):
        out = str(tmp_path / ('out_%s_%s' % (os.path.basename(map_dir), frame)))
        return _report_of(map_dir, synthetic_dirs[1], out, '--dynamics-frame', frame)

    original = report_of(synthetic_dirs[0], 'map-fit')
    moved = report_of(turned, 'map-fit')
    moved_first = report_of(turned, 'first-scan')
    assert original['dynamics']['frame'] == 'map-fit'
    assert moved_first['dynamics']['frame'] == 'first-scan'
    np.testing.assert_allclose(moved['frame']['t_map_world_fit'],
                               original['frame']['t_map_world_fit'], atol=1e-9)
    assert moved['frame']['map_fit']['rotation_deg'] == pytest.approx(np.degrees(yaw), abs=0.2)
    for a, b_ in zip(original['sessions'], moved['sessions']):
        assert b_['ate_rmse_map_fit_m'] == pytest.approx(a['ate_rmse_map_fit_m'], abs=1e-9)
        assert b_['ate_rmse_m'] > a['ate_rmse_m'] + 0.2  # the first-scan frame moved
    assert moved['dynamics']['static'] == original['dynamics']['static']
    assert moved['dynamics']['low'] == original['dynamics']['low']
    assert moved_first['dynamics']['static']['sa'] < original['dynamics']['static']['sa']

    # The fit minimises the squared position error of all poses together: never above the
    # first scan's frame, and it does not align the sessions separately (s00 and s01 are off
    # by different shifts, synthetic_case.EXPECTED).
    def sum_squares(report, key):
        return sum(x[key] ** 2 * x['ate_poses'] for x in report['sessions'])
    assert sum_squares(original, 'ate_rmse_map_fit_m') <= sum_squares(original, 'ate_rmse_m')
    assert sum_squares(original, 'ate_rmse_map_fit_m') > 1e-4
    assert all(x['ate_rmse_aligned_m'] < 1e-6 for x in original['sessions'])
