"""End to end (issue 6's test): two `small` sessions of the simulated campus, mapped one after
the other into one map by the offline runner (the second found in the map by place recognition,
without an initial guess), then judged by the evaluator against the simulator's ground truth.

The second session drives most of the first one's route (docs/simulator.md): the submaps that
overlap history in ground truth must be placed by inter-session loops, none wrongly, and the
others left undefined. Only the evaluator reads the truth. Takes about 1.5-2 minutes.
Measured (session 34, seed 5): s01 has 10 submaps, 7 overlapping history in truth, all 7
placed (8 correct in all), 0 wrong, 2 undefined (new place), 0 missed; 6 inter loops, all
correct, median error 0.060 m / 0.40 deg; recall@1 0.92 over 539 queries (335 revisits).
Needs the built workspace (rosrun), like test_workspace.py; its files (two bags of ~200 MB)
are removed when the module's tests are done.
"""

import json
import os
import shutil
import subprocess

import pytest

REPO = os.path.realpath(os.path.join(os.path.dirname(__file__), '..', '..'))
SEED = 5  # not one of the campus seeds the defaults were tuned on (1, 2)
TIMEOUT_S = 900


def _run(cmd, log):
    with open(log, 'w') as out:
        proc = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, timeout=TIMEOUT_S,
                              check=False)
    if proc.returncode != 0:
        with open(log) as f:
            tail = f.read()[-3000:]
        raise AssertionError('%s exited with %d:\n%s' % (' '.join(cmd), proc.returncode, tail))


@pytest.fixture(scope='module')
def report(tmp_path_factory):
    assert 'ROS_PACKAGE_PATH' in os.environ, 'run inside the built workspace (catkin run_tests)'
    root = tmp_path_factory.mktemp('small_sessions')
    try:
        yield _map_and_evaluate(root)
    finally:
        shutil.rmtree(str(root), ignore_errors=True)


def _map_and_evaluate(root):
    sim, map_dir, out = str(root / 'sim'), str(root / 'map'), str(root / 'report')
    _run(['rosrun', 'multisession_mapper', 'simulate_campus', '--profile', 'small',
          '--sessions', '2', '--seed', str(SEED), '--out', sim], str(root / 'simulate.log'))
    for session in ('s00', 's01'):
        _run(['rosrun', 'multisession_mapper', 'offline_mapper', '--quiet',
              '--bag', os.path.join(sim, session + '.bag'), '--map', map_dir,
              '--session', session], str(root / ('map_%s.log' % session)))
    _run([os.path.join(REPO, 'scripts', 'evaluate'), '--map', map_dir, '--truth', sim,
          '--out', out, '--no-dynamics', '--no-plots', '--quiet'], str(root / 'evaluate.log'))
    with open(os.path.join(out, 'report.json')) as f:
        return json.load(f)


def _second(report):
    sessions = {s['name']: s for s in report['sessions']}
    assert set(sessions) == {'s00', 's01'}, sorted(sessions)
    return sessions['s01']


def test_every_overlapping_submap_is_placed_and_none_wrongly(report):
    s01 = _second(report)
    assert s01['has_history']
    assert s01['submaps_unknown'] == 0, s01['submap_status']
    assert s01['submaps_wrong'] == 0, s01['submap_status']
    overlapping = s01['submaps_with_truth_overlap']
    assert overlapping >= 3, s01
    # The paper's table (target >= 97 % of the overlapping ones matched): `submaps_correct` also
    # counts correct loops of submaps that do not overlap by the evaluator's rule, so the
    # overlapping ones left unmatched are what is judged.
    matched = overlapping - s01['submaps_undefined_missed']
    assert matched >= 0.97 * overlapping, s01['submap_status']
    assert s01['submaps_correct'] >= matched, s01['submap_status']


def test_the_accepted_loops_are_right_and_accurate(report):
    s01 = _second(report)
    assert s01['inter_loops_accepted'] >= 2, s01
    assert s01['inter_loops_wrong'] == 0
    assert s01['sequence_loops_wrong'] == 0
    assert s01['proximity_loops_wrong'] == 0
    assert s01['loops_unjudged'] == 0
    # Issue 6's target for the relative pose of accepted inter-session loops (median).
    assert s01['inter_loop_trans_err_median_m'] <= 0.1
    assert s01['inter_loop_rot_err_median_deg'] <= 0.5


def test_the_place_recognition_log_is_scored(report):
    pr = _second(report)['place_recognition']
    assert pr['queries'] > 100, pr
    assert pr['revisits'] > 0.5 * pr['queries'], pr
    # Most revisits find a scan of the same place as their nearest descriptor.
    assert pr['recall_at_1'] >= 0.5, pr
    assert 0.0 < pr['f1max'] <= 1.0, pr
