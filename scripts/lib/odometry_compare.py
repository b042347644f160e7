"""Compares odometry trajectories (TUM) with a ground-truth trajectory: the peer comparison of
scripts/bench.d/kiss_icp.sh (issue 5).

usage: odometry_compare.py --truth TRUTH.tum --json OUT.json NAME=EST.tum[:MS_PER_SCAN] ...

Per estimate: ATE RMSE with both trajectories expressed relative to their first pose (what a
user of the odometry sees; no fitted alignment), ATE after SE(3) Umeyama alignment, RPE over
100 m (evo's path-based pairs, %), the largest tilt error (angle between the estimated and the
true up axes, relative to the first pose) and the final drift in % of the path. Prints a
Markdown table and writes the figures as JSON. Reads ground truth: evaluation only.
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.realpath(__file__)), '..', '..', 'python'))
from multisession_mapper_eval import trajectory as tr  # noqa: E402


def figures(estimate, truth):
    est, ref = tr.associate(estimate, truth)
    if len(est) < 2:
        return {'poses': int(len(est))}
    est0 = np.einsum('ij,njk->nik', tr.inverse(est[0]), est)
    ref0 = np.einsum('ij,njk->nik', tr.inverse(ref[0]), ref)
    err = np.linalg.norm(est0[:, :3, 3] - ref0[:, :3, 3], axis=1)
    up = np.clip(np.einsum('ni,ni->n', est0[:, :3, 2], ref0[:, :3, 2]), -1.0, 1.0)
    path = float(np.sum(np.linalg.norm(np.diff(ref0[:, :3, 3], axis=0), axis=1)))
    rpe = tr.rpe(est0, ref0, 100.0)
    return {
        'poses': int(len(est)),
        'path_m': path,
        'ate_first_pose_rmse_m': float(np.sqrt(np.mean(err ** 2))),
        'ate_aligned_rmse_m': tr.ate(est0, ref0, align=True)['rmse'],
        'rpe_100m_pct': rpe['pct'],
        'max_tilt_error_deg': float(np.degrees(np.arccos(up.min()))),
        'final_drift_pct': float(100.0 * err[-1] / max(path, 1e-9)),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--truth', required=True)
    parser.add_argument('--json', required=True)
    parser.add_argument('estimates', nargs='+', help='NAME=EST.tum[:MS_PER_SCAN]')
    args = parser.parse_args()
    truth = tr.read_tum(args.truth)
    result = {}
    for spec in args.estimates:
        name, _, rest = spec.partition('=')
        path, _, ms = rest.partition(':')
        if not os.path.isfile(path):
            result[name] = {'error': 'no trajectory %s' % path}
            continue
        result[name] = figures(tr.read_tum(path), truth)
        result[name]['ms_per_scan'] = float(ms) if ms else None
    print('| odometry | poses | path [m] | ATE from first pose [m] | ATE aligned [m] | '
          'RPE 100 m [%] | max tilt error [deg] | final drift [%] | ms/scan |')
    print('|---|---|---|---|---|---|---|---|---|')
    fmt = lambda v, f: '-' if v is None else f % v  # noqa: E731
    for name, r in result.items():
        print('| %s | %s | %s | %s | %s | %s | %s | %s | %s |' % (
            name, r.get('poses', '-'), fmt(r.get('path_m'), '%.0f'),
            fmt(r.get('ate_first_pose_rmse_m'), '%.2f'), fmt(r.get('ate_aligned_rmse_m'), '%.2f'),
            fmt(r.get('rpe_100m_pct'), '%.2f'), fmt(r.get('max_tilt_error_deg'), '%.2f'),
            fmt(r.get('final_drift_pct'), '%.2f'), fmt(r.get('ms_per_scan'), '%.1f')))
    with open(args.json, 'w') as f:
        json.dump(result, f, indent=1)
    return 0


if __name__ == '__main__':
    sys.exit(main())
