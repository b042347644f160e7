import os

import numpy as np

from multisession_mapper_eval import plots


def test_all_plots_are_written(tmp_path):
    rng = np.random.default_rng(0)
    data = {'map_points': {'s00': rng.uniform(0, 10, (500, 3)),
                           's01': rng.uniform(5, 15, (500, 3))},
            'removed': rng.uniform(0, 10, (20, 3)),
            'est_traj': {'s00': np.c_[np.arange(10.0), np.zeros((10, 2))]},
            'truth_traj': {'s00': np.c_[np.arange(10.0), np.ones((10, 2))]},
            'pr_curves': {'s01': {'precision': [1.0, 0.5], 'recall': [0.2, 0.4]}},
            'sessions': [{'name': 's01', 'submaps_correct': 3, 'submaps_undefined_new': 1,
                          'submaps_undefined_missed': 1, 'submaps_wrong': 0}]}
    files = plots.write_all(str(tmp_path), data)
    assert sorted(files) == ['loop_table.png', 'map_top.png', 'place_recognition_pr.png',
                             'trajectories.png']
    for name in files:
        with open(os.path.join(str(tmp_path), name), 'rb') as f:
            assert f.read(8) == b'\x89PNG\r\n\x1a\n'
