"""report.json, report.md and the tables printed on the terminal."""

import json
import math
import os

import numpy as np


def clean(value):
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(value, dict):
        return {str(k): clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return [clean(v) for v in value.tolist()]
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (np.floating, float)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def _fmt(value, spec='%.3f', scale=1.0):
    if value is None:
        return '-'
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, int):
        return str(value)
    return spec % (value * scale)


def _table(header, rows):
    lines = ['| ' + ' | '.join(header) + ' |', '|' + '|'.join('---' for _ in header) + '|']
    lines += ['| ' + ' | '.join(str(c) for c in row) + ' |' for row in rows]
    return '\n'.join(lines)


def _fit_text(fit):
    if not fit:
        return 'not computed'
    return 'the first scan\'s frame turned by %.3f deg and moved by %.3f m' % (
        fit['rotation_deg'], fit['translation_m'])


def markdown(report):
    s = report['sessions']
    parts = ['# Evaluation report', '',
             'Map: `%s`  ' % report['inputs']['map'], 'Truth: `%s`' % report['inputs']['truth'],
             '']
    parts += ['## Trajectories', '',
              'ATE in the map frame, i.e. the first scan\'s (no alignment); map fit = after '
              'one SE(3) fit of the whole map (all sessions at once: %s); aligned = per '
              'session, SE(3) Umeyama. RPE with evo\'s path-based pairs.'
              % _fit_text(report['frame'].get('map_fit')), '',
              _table(['session', 'scans', 'duration [s]', 'ATE RMSE [m]', 'ATE max [m]',
                      'ATE map fit [m]', 'ATE aligned [m]', 'RPE 10 m [%]', 'RPE 100 m [%]',
                      'RPE 100 m [deg/100m]'],
                     [[x['name'], x['scans'], _fmt(x['duration_s'], '%.1f'),
                       _fmt(x['ate_rmse_m']), _fmt(x['ate_max_m']),
                       _fmt(x.get('ate_rmse_map_fit_m')), _fmt(x['ate_rmse_aligned_m']),
                       _fmt(x['rpe_10m_pct'], '%.2f'), _fmt(x['rpe_100m_pct'], '%.2f'),
                       _fmt(x['rpe_100m_deg'], '%.2f')] for x in s]), '']
    parts += ['## Inter-session loop closure (the reference paper\'s table)', '',
              _table(['session', 'submaps', 'correct', 'of which by sequence', 'undefined (new)',
                      'undefined (missed)',
                      'wrong', 'overlapping', 'loop err median [m / deg]', 'intra accepted',
                      'intra correct', 'intra wrong'],
                     [[x['name'], x['submaps_total']] +
                      ([x['submaps_correct'], x.get('submaps_correct_by_sequence', 0),
                        x['submaps_undefined_new'], x['submaps_undefined_missed'],
                        x['submaps_wrong'], x['submaps_with_truth_overlap']]
                       if x.get('has_history', True) else ['-'] * 6) + [
                       '%s / %s' % (_fmt(x['inter_loop_trans_err_median_m']),
                                    _fmt(x['inter_loop_rot_err_median_deg'], '%.2f')),
                       x['intra_loops_accepted'], x['intra_loops_correct'],
                       x['intra_loops_wrong']] for x in s]), '']
    parts += ['## Place recognition (per scan)', '',
              _table(['session', 'queries', 'revisits', 'F1max', 'recall@1', 'recall@5',
                      'max recall @ P=1', 'P / R at d_alpha'],
                     [[x['name'], x['place_recognition']['queries'],
                       x['place_recognition']['revisits'], _fmt(x['place_recognition']['f1max']),
                       _fmt(x['place_recognition']['recall_at_1']),
                       _fmt(x['place_recognition']['recall_at_5']),
                       _fmt(x['place_recognition']['max_recall_at_full_precision']),
                       '%s / %s' % (_fmt(x['place_recognition']['precision_at_threshold']),
                                    _fmt(x['place_recognition']['recall_at_threshold']))]
                      for x in s]), '']
    d = report['dynamics']
    if d.get('evaluated'):
        rows = [['static', _fmt(d['static']['sa'], '%.2f', 100), '-', '-', '-',
                 d['points']['static']],
                ['canopy (static)', _fmt(d['canopy']['sa'], '%.2f', 100), '-', '-', '-',
                 d['points']['canopy']]]
        names = {'low': 'low-dynamic', 'high': 'high-dynamic', 'all_dynamic': 'all dynamic'}
        for key in ('low', 'high', 'all_dynamic'):
            rows.append([names[key], _fmt(d[key]['sa'], '%.2f', 100),
                         _fmt(d[key]['da'], '%.2f', 100),
                         _fmt(d[key]['aa'], '%.2f', 100), _fmt(d[key]['ha'], '%.2f', 100),
                         d['points'][key if key != 'all_dynamic' else 'low'] +
                         (d['points']['high'] if key == 'all_dynamic' else 0)])
        origins = {'map-fit': '; map compared after the whole-map SE(3) fit',
                   'first-scan': '; map compared in the first scan\'s frame'}.get(
                       d.get('frame'), '')
        if d.get('submap_origins') == 'truth':
            origins = ('; submaps at their TRUE origins: the content of the map without its '
                       'alignment error, a diagnosis')
        parts += ['## Dynamic removal (DynamicMap definitions, %%; kept radius %.2f m%s)'
                  % (d['kept_radius_m'], origins), '',
                  _table(['set', 'SA', 'DA', 'AA', 'HA', 'GT points'], rows), '']
        parts += _breakdown_tables(d.get('breakdown'))
    else:
        parts += ['## Dynamic removal', '', 'not evaluated: %s' % d.get('reason', ''), '']
    m = report['map']
    parts += ['## Map', '',
              _table(['session', 'points (active submaps)', 'active submaps', 'bytes on disk'],
                     [[name, p, n, b] for name, p, n, b in
                      zip([x['name'] for x in s], m['points_per_session'],
                          m['active_submaps_per_session'], m['bytes_on_disk_per_session'])]
                     + [['total', m['points_total'], m['submaps_active'], m['bytes_on_disk']]]),
              '']
    t = report['timing']
    parts += ['## Timing', '',
              _table(['figure', 'value'],
                     [['real-time factor', _fmt(t['realtime_factor'], '%.2f')],
                      ['deskew + odometry [ms/scan, median]',
                       _fmt(t['odometry_ms_median'], '%.2f')],
                      ['of it ICP registration [ms/scan, median]',
                       _fmt(t.get('odometry_registration_ms_median'), '%.2f')],
                      ['of it map-ground refinement [ms/scan, median]',
                       _fmt(t.get('odometry_map_ground_ms_median'), '%.2f')],
                      ['ICP iterations per scan [median]',
                       _fmt(t.get('odometry_icp_iterations_median'), '%.0f')],
                      ['descriptor [ms/scan]', _fmt(t['descriptor_ms_median'], '%.3f')],
                      ['query [ms/scan]', _fmt(t['query_ms_median'], '%.3f')],
                      ['global registration [s/pair]', _fmt(t['global_registration_s_median'])],
                      ['dynamic detection [s/pair]',
                       _fmt(t['dynamic_detection_s_per_pair_median'])],
                      ['merge [s/session]', ', '.join(_fmt(v, '%.1f')
                                                      for v in t['merge_s_per_session'])],
                      ['peak RSS [MB]', _fmt(t['peak_rss_mb'], '%.0f')]]), '']
    if report.get('warnings'):
        parts += ['## Warnings', ''] + ['- ' + w for w in report['warnings']] + ['']
    return '\n'.join(parts)


def _breakdown_tables(b):
    """The dynamic-removal breakdown (by distance to the path, by presence, by class) as
    markdown."""
    if not b:
        return []
    rows = [['%.0f-%s' % (r['from_m'], '%.0f' % r['to_m'] if r['to_m'] is not None else ''),
             _fmt(r['sa'], '%.2f', 100), r['static_points'], _fmt(r['low_da'], '%.2f', 100),
             r['low_points'], _fmt(r['high_da'], '%.2f', 100), r['high_points']]
            for r in b.get('by_range', [])]
    parts = ['By distance to the nearest truth scan position [m]:', '',
             _table(['distance', 'SA', 'static', 'low-dynamic DA', 'low', 'high-dynamic DA',
                     'high'], rows), '']
    presence = b.get('low_by_presence', [])
    if presence:
        parts += ['Low-dynamic objects by the sessions they are present in:', '',
                  _table(['present in', 'objects', 'points', 'DA'],
                         [[' + '.join(p['present_in']) or '-', p['objects'], p['points'],
                           _fmt(p['da'], '%.2f', 100)] for p in presence]), '']
    by_class = b.get('by_class', [])
    if by_class:
        parts += ['By class (static points lost, dynamic points kept):', '',
                  _table(['class', 'SA', 'static', 'lost', 'low-dynamic DA', 'low', 'kept',
                          'high-dynamic DA', 'high', 'kept'],
                         [[c['name'], _fmt(c['sa'], '%.2f', 100), c['static_points'],
                           c['static_points'] - c['static_kept'],
                           _fmt(c['low_da'], '%.2f', 100), c['low_points'],
                           c['low_points'] - c['low_removed'],
                           _fmt(c['high_da'], '%.2f', 100), c['high_points'],
                           c['high_points'] - c['high_removed']] for c in by_class]), '']
    return parts


def write(report, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    report = clean(report)
    with open(os.path.join(out_dir, 'report.json'), 'w') as f:
        json.dump(report, f, indent=2, sort_keys=False)
        f.write('\n')
    text = markdown(report)
    with open(os.path.join(out_dir, 'report.md'), 'w') as f:
        f.write(text)
    return text
