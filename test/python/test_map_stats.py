from multisession_mapper_eval import io
from multisession_mapper_eval import map_stats


def test_points_and_bytes(synthetic_dirs):
    map_dir = io.MapDir(synthetic_dirs[0])
    m = map_stats.compute(map_dir)
    # s00: 126 kept GT points in submap 0 + 1 point in each of its 2 other submaps;
    # s01: 1 point in each of its 4 active submaps (submap 4 is fused).
    assert m['points_per_session'] == [128, 4]
    assert m['points_total'] == 132
    assert m['active_submaps_per_session'] == [3, 4] and m['submaps_total'] == 8
    assert m['bytes_on_disk'] == io.directory_bytes(synthetic_dirs[0])
    assert sum(m['bytes_on_disk_per_session']) + m['bytes_shared'] == m['bytes_on_disk']
    assert all(b > 0 for b in m['bytes_on_disk_per_session']) and m['bytes_shared'] > 0
