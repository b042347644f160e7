import pytest

from multisession_mapper_eval import io
from multisession_mapper_eval import loops

import synthetic_case

E = synthetic_case.EXPECTED


def _tables(map_path, truth_path, **kwargs):
    map_dir = io.MapDir(map_path)
    truth = io.Truth(truth_path)
    trajectories = {n: truth.trajectory(n) for n in map_dir.session_names}
    options = loops.LoopOptions(**kwargs)
    return [loops.session_table(map_dir, i, trajectories, options)
            for i in range(len(map_dir.session_names))]


def test_paper_table_on_hand_made_map(synthetic_dirs):
    tables = _tables(*synthetic_dirs)
    for key in ('submaps_total', 'submaps_correct', 'submaps_wrong', 'submaps_undefined_new',
                'submaps_undefined_missed', 'intra_loops_accepted', 'intra_loops_correct',
                'intra_loops_wrong', 'inter_loops_accepted', 'inter_loops_correct',
                'proximity_loops_accepted', 'proximity_loops_correct'):
        assert [t[key] for t in tables] == E[key], key
    assert tables[1]['submap_status'] == {'0': 'correct', '1': 'wrong', '2': 'undefined_missed',
                                          '3': 'undefined_new', '4': 'wrong'}
    assert tables[1]['inter_loop_trans_err_median_m'] == pytest.approx(0.1, abs=1e-6)
    assert tables[0]['intra_loop_rot_err_median_deg'] == pytest.approx(2.5, abs=1e-6)
    # First session: no history, so every inter-session count is 0.
    assert tables[0]['submaps_correct'] + tables[0]['submaps_wrong'] == 0
    t = tables[1]
    assert (t['submaps_correct'] + t['submaps_wrong'] + t['submaps_undefined_new']
            + t['submaps_undefined_missed']) == t['submaps_total']


def test_thresholds_are_options(synthetic_dirs):
    # With a 1.5 m bound the 1 m-off match of submap 1 becomes correct.
    tables = _tables(*synthetic_dirs, max_trans_m=1.5)
    assert tables[1]['submaps_correct'] == 2 and tables[1]['submaps_wrong'] == 1
    # A 40 m overlap radius makes submap 3 overlapping: it becomes "missed".
    tables = _tables(*synthetic_dirs, overlap_radius_m=40.0)
    assert tables[1]['submaps_undefined_new'] == 0
    assert tables[1]['submaps_undefined_missed'] == 2
    # Submap 4's exact-pose match with s00/0 stays wrong: those two submaps are 61 m apart.
    assert tables[1]['submaps_wrong'] == 2


def test_intra_session_loops_are_judged_by_their_pose_alone(synthetic_dirs):
    # With an overlap radius of a micrometre no two submaps' truth paths "overlap": the exact
    # inter-session match of s01/0 is then wrong (place recognition needs a real revisit), but
    # the exact intra-session edge s00/1 -> s00/0 stays correct (the graph edge is right) and
    # the 5 deg-off one stays wrong.
    tables = _tables(*synthetic_dirs, overlap_radius_m=1e-6)
    assert tables[1]['submap_status']['0'] == 'wrong'
    assert tables[0]['intra_loops_correct'] == 1 and tables[0]['intra_loops_wrong'] == 1


def test_submap_missing_from_manifest_is_unknown(synthetic_dirs, tmp_path):
    import shutil
    map_copy = str(tmp_path / 'map')
    shutil.copytree(synthetic_dirs[0], map_copy)
    with open(map_copy + '/loops/s01.csv', 'a') as f:   # submap 7 does not exist
        f.write('inter,s01,7,s00,0,accepted,0.97,0.8,0,0,0,0,0,0,1,\n')
    tables = _tables(map_copy, synthetic_dirs[1])
    assert tables[1]['submaps_total'] == 6 and tables[1]['submaps_unknown'] == 1
    assert tables[1]['loops_unjudged'] == 1 and tables[1]['submaps_wrong'] == 2
    assert tables[1]['submap_status']['7'] == 'unknown'


def test_sequence_loops_count_in_the_table_and_separately(synthetic_dirs, tmp_path):
    import shutil
    map_copy = str(tmp_path / 'map')
    shutil.copytree(synthetic_dirs[0], map_copy)
    with open(map_copy + '/loops/s01.csv') as f:
        lines = f.read().splitlines()
    # Submap 2 ("missed": its `inter` candidate was rejected) gets an exact sequence-guided loop,
    # submap 3 (a new place) one with the same pose as submap 2's, which is wrong there.
    proximity = next(l for l in lines if l.startswith('inter_proximity,s01,2,'))
    sequence = 'inter_sequence' + proximity[len('inter_proximity'):]
    wrong = sequence.replace('inter_sequence,s01,2,', 'inter_sequence,s01,3,', 1)
    with open(map_copy + '/loops/s01.csv', 'a') as f:
        f.write(sequence + '\n' + wrong + '\n')
    before = _tables(*synthetic_dirs)[1]
    t = _tables(map_copy, synthetic_dirs[1])[1]
    assert t['submap_status']['2'] == 'correct' and t['submap_status']['3'] == 'wrong'
    assert t['submaps_correct'] == before['submaps_correct'] + 1
    assert t['submaps_correct_by_sequence'] == 1
    assert t['sequence_loops_accepted'] == 2
    assert t['sequence_loops_correct'] == 1 and t['sequence_loops_wrong'] == 1
    assert t['inter_loops_accepted'] == before['inter_loops_accepted']
    assert before['submaps_correct_by_sequence'] == 0
