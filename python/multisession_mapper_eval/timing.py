"""Timing figures from timing/<session>.yaml (docs/map_format.md).

Across sessions: per-scan and per-pair figures are the median of the sessions' medians;
realtime_factor = sum of bag durations / sum of wall times (>1 is faster than real time);
peak_rss_mb is the maximum over sessions; merge_s_per_session lists merge_s in merge order.
Missing values are None.
"""

import numpy as np


def _get(record, *keys):
    for key in keys:
        if not isinstance(record, dict) or key not in record:
            return None
        record = record[key]
    try:
        return float(record)
    except (TypeError, ValueError):
        return None


def _median(values):
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None


def session_figures(record):
    record = record or {}
    wall = _get(record, 'wall_time_s')
    duration = _get(record, 'bag_duration_s')
    return {
        'wall_time_s': wall, 'bag_duration_s': duration,
        'realtime_factor': duration / wall if wall and duration is not None else None,
        'odometry_ms_median': _get(record, 'per_scan_ms', 'deskew_odometry', 'median'),
        'odometry_ms_p95': _get(record, 'per_scan_ms', 'deskew_odometry', 'p95'),
        'odometry_registration_ms_median': _get(record, 'odometry_stages_ms', 'registration',
                                                'median'),
        'odometry_map_ground_ms_median': _get(record, 'odometry_stages_ms', 'map_ground',
                                              'median'),
        'odometry_icp_iterations_median': _get(record, 'odometry_icp_per_scan', 'iterations',
                                               'median'),
        'descriptor_ms_median': _get(record, 'per_scan_ms', 'descriptor', 'median'),
        'query_ms_median': _get(record, 'per_scan_ms', 'query', 'median'),
        'submap_building_ms_median': _get(record, 'per_scan_ms', 'submap_building', 'median'),
        'intra_loop_s_median': _get(record, 'per_submap_s', 'intra_loop', 'median'),
        'global_registration_s_median': _get(record, 'per_pair_s', 'global_registration',
                                             'median'),
        'dynamic_detection_s_per_pair_median': _get(record, 'per_pair_s', 'dynamic_detection',
                                                    'median'),
        'merge_s': _get(record, 'merge_s'),
        'map_bytes_after_merge': _get(record, 'map_bytes_after_merge'),
        'peak_rss_mb': _get(record, 'peak_rss_mb'),
    }


def combine(per_session):
    """The `timing` section of report.json from the per-session figures (merge order)."""
    walls = [s['wall_time_s'] for s in per_session]
    durations = [s['bag_duration_s'] for s in per_session]
    pairs = [(d, w) for d, w in zip(durations, walls) if d is not None and w]
    rss = [s['peak_rss_mb'] for s in per_session if s['peak_rss_mb'] is not None]
    out = {'realtime_factor': (sum(d for d, _ in pairs) / sum(w for _, w in pairs)
                               if pairs else None),
           'wall_time_s_total': float(sum(w for _, w in pairs)) if pairs else None,
           'merge_s_per_session': [s['merge_s'] for s in per_session],
           'peak_rss_mb': max(rss) if rss else None}
    for key in ('odometry_ms_median', 'odometry_registration_ms_median',
                'odometry_map_ground_ms_median',
                'odometry_icp_iterations_median', 'descriptor_ms_median', 'query_ms_median',
                'submap_building_ms_median', 'intra_loop_s_median',
                'global_registration_s_median', 'dynamic_detection_s_per_pair_median'):
        out[key] = _median([s[key] for s in per_session])
    return out
