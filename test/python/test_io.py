import os

import numpy as np
import pytest

from multisession_mapper_eval import io

import synthetic_case


def test_map_directory_reader(synthetic_dirs):
    map_dir = io.MapDir(synthetic_dirs[0])
    assert map_dir.session_names == ['s00', 's01']
    assert len(map_dir.submaps) == 8
    sm = map_dir.submaps_of('s01')[4]
    assert sm.status == 'fused' and len(sm.scan_stamps) == 20
    np.testing.assert_allclose(sm.origin, synthetic_case.S01.poses[80], atol=1e-9)
    rows = map_dir.loops('s01')
    assert [r.status for r in rows][:3] == ['accepted', 'accepted', 'rejected']
    assert rows[4].history_submap is None and rows[4].pose is None
    pr = map_dir.place_recognition('s01')
    assert len(pr) == 6 and pr[2].top_k[1][0] == 's00' and pr[4].matched is False
    assert map_dir.place_recognition('s00') is None
    assert map_dir.timing('s01')['merge_s'] == 3.0
    points = map_dir.submaps_of('s00')[0].load_points()
    assert len(points) == 126


def test_loop_rows_read_the_structure_overlap_when_present():
    base = {'kind': 'inter', 'current_submap': '3', 'history_submap': '1', 'status': 'accepted',
            'overlap_ratio': '0.8'}
    assert io.LoopRow(base).structure_overlap_ratio is None  # maps before the column existed
    row = io.LoopRow(dict(base, structure_overlap_ratio='0.62'))
    assert row.structure_overlap_ratio == pytest.approx(0.62)
    assert row.overlap_ratio == pytest.approx(0.8)


def test_truth_reader(synthetic_dirs):
    truth = io.Truth(synthetic_dirs[1])
    assert truth.resolve('s01') == 's01' and truth.resolve('nope') is None
    t = truth.trajectory('s00')
    np.testing.assert_allclose(t.poses[0], synthetic_case.T_WORLD_MAP, atol=1e-8)
    points, labels, ids, ranges = truth.labels('s01')
    assert ranges is None  # written without the simulator's range field
    assert len(points) == len(labels) == len(ids) == 6 + 105 + 10 + 6 + 3 + 5 + 4
    assert set(labels.tolist()) == {0, 1, 6, 7, 9, 10}


def test_missing_manifest_is_a_clear_error(tmp_path):
    with pytest.raises(io.EvalInputError, match='manifest.yaml'):
        io.MapDir(str(tmp_path))
    (tmp_path / 'manifest.yaml').write_text('a: [1, 2\n')
    with pytest.raises(io.EvalInputError, match='malformed YAML'):
        io.MapDir(str(tmp_path))


def test_directory_bytes(tmp_path):
    (tmp_path / 'a').write_bytes(b'x' * 10)
    os.makedirs(str(tmp_path / 'd'))
    (tmp_path / 'd' / 'b').write_bytes(b'x' * 5)
    assert io.directory_bytes(str(tmp_path)) == 15


def test_world_blocks_no_metric_needs_are_omitted():
    import yaml
    text = ('format: x\nterrain:\n  cols: 2\n  heights:\n    - [1, 2]\n    - [3, 4]\n'
            'objects:\n  - id: 1\n    class: moving_car\n    parts:\n      - {shape: box}\n'
            '    trajectory:\n      - [0, 1, 2, 3, 0]\n    sessions: [s00]\n'
            '  - id: 2\n    class: wall\n    sessions: [s00, s01]\n')
    world = yaml.safe_load(io._drop_blocks(text, ('terrain', 'parts', 'trajectory')))
    assert world['terrain'] == 'omitted'
    assert world['objects'][0] == {'id': 1, 'class': 'moving_car', 'parts': 'omitted',
                                   'trajectory': 'omitted', 'sessions': ['s00']}
    assert world['objects'][1]['sessions'] == ['s00', 's01']
    # PyYAML's own block style puts nested sequences at the key's indentation.
    dumped = yaml.safe_dump({'objects': [{'id': 3, 'trajectory': [[0, 1], [2, 3]],
                                          'sessions': ['a']}, {'id': 4}]}, sort_keys=False)
    world = yaml.safe_load(io._drop_blocks(dumped, ('trajectory',)))
    assert world['objects'] == [{'id': 3, 'trajectory': 'omitted', 'sessions': ['a']},
                                {'id': 4}]
