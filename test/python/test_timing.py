import pytest

from multisession_mapper_eval import timing

import synthetic_case

E = synthetic_case.EXPECTED


def test_combine_sessions():
    per_session = [timing.session_figures(synthetic_case.TIMING[n]) for n in ('s00', 's01')]
    assert per_session[1]['realtime_factor'] == pytest.approx(2.5)
    t = timing.combine(per_session)
    for key in ('realtime_factor', 'odometry_ms_median', 'global_registration_s_median',
                'dynamic_detection_s_per_pair_median', 'peak_rss_mb'):
        assert t[key] == pytest.approx(E[key]), key
    assert t['merge_s_per_session'] == E['merge_s_per_session']


def test_missing_records_give_none():
    t = timing.combine([timing.session_figures(None)])
    assert t['realtime_factor'] is None and t['peak_rss_mb'] is None
    assert t['merge_s_per_session'] == [None]


def test_optional_growth_record():
    figures = timing.session_figures({'map_bytes_after_merge': 12345})
    assert figures['map_bytes_after_merge'] == 12345.0
    assert timing.session_figures({})['map_bytes_after_merge'] is None


def test_odometry_stage_and_icp_work():
    records = [{'odometry_stages_ms': {'registration': {'median': 12.0},
                                       'map_ground': {'median': 1.0}},
                'odometry_icp_per_scan': {'iterations': {'median': 9}}},
               {'odometry_stages_ms': {'registration': {'median': 16.0}},
                'odometry_icp_per_scan': {'iterations': {'median': 11}}},
               {}]
    t = timing.combine([timing.session_figures(r) for r in records])
    assert t['odometry_registration_ms_median'] == pytest.approx(14.0)
    assert t['odometry_map_ground_ms_median'] == pytest.approx(1.0)  # the one record with it
    assert t['odometry_icp_iterations_median'] == pytest.approx(10.0)
    assert timing.session_figures({})['odometry_icp_iterations_median'] is None
