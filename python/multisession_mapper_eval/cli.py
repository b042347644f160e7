"""`evaluate --map MAP_DIR --truth SIM_DIR [--out REPORT_DIR]`: the whole evaluation.

Reads only the map directory and the simulator's ground truth; writes report.json, report.md
and PNG plots into REPORT_DIR and prints the tables. See docs/evaluation.md.
"""

import argparse
import os
import sys
import time

import numpy as np

from . import dynamics
from . import io
from . import loops
from . import map_stats
from . import place_recognition
from . import report as report_mod
from . import timing
from . import trajectory as tr


def build_parser():
    p = argparse.ArgumentParser(
        prog='evaluate', description='Evaluate a multisession_mapper map directory against '
        'the simulator ground truth (docs/evaluation.md).')
    p.add_argument('--map', required=True, help='map directory written by the pipeline')
    p.add_argument('--truth', required=True, help='simulator output directory (sessions.yaml)')
    p.add_argument('--out', help='report directory (default: <MAP_DIR>_report)')
    p.add_argument('--loop-max-trans-m', type=float, default=0.3,
                   help='correct loop: translation error bound [m] (default 0.3)')
    p.add_argument('--loop-max-rot-deg', type=float, default=1.0,
                   help='correct loop: rotation error bound [deg] (default 1)')
    p.add_argument('--overlap-radius-m', type=float, default=10.0,
                   help='ground-truth overlap: scan positions within this radius [m] (default 10)')
    p.add_argument('--overlap-min-fraction', type=float, default=0.5,
                   help='a submap overlaps history when this fraction of its scans has a '
                   'history scan within --overlap-radius-m (default 0.5)')
    p.add_argument('--pr-radius-m', type=float, default=5.0,
                   help='place recognition: true match within this distance [m] (default 5)')
    p.add_argument('--pr-k', type=int, default=5, help='recall@k uses the first k of top_k')
    p.add_argument('--observed-rule', choices=('footprint', 'radius'), default='footprint',
                   help='which sessions saw the place of a parked car or movable object: '
                   'footprint (default): the session has labelled returns inside the object\'s '
                   'box grown by --footprint-margin-m (the ground under a vanished car); '
                   'radius: its trajectory passed within --observe-radius-m')
    p.add_argument('--footprint-margin-m', type=float, default=0.3,
                   help='footprint rule: box growth [m] (default 0.3)')
    p.add_argument('--footprint-min-points', type=int, default=5,
                   help='footprint rule: returns needed inside the box (default 5)')
    p.add_argument('--observe-radius-m', type=float, default=30.0,
                   help='radius rule: a session observed an object when its truth trajectory '
                   'passes within this horizontal distance [m] of it (default 30)')
    p.add_argument('--kept-radius-m', type=float, default=None,
                   help='a ground-truth point is kept when a map point lies within this radius '
                   '[m] (default: max(0.2, the submap voxel size from the manifest parameters))')
    p.add_argument('--kept-rule', choices=('same_category', 'any'), default='same_category',
                   help='same_category (default): a ground-truth point is kept by map points '
                   'whose nearest ground-truth point has its category; any: by any map point')
    p.add_argument('--eval-range-m', type=float, default=None,
                   help='evaluate dynamics only on ground-truth points within this distance of '
                   'a truth scan position [m] (default: the submap max_point_range_m from the '
                   'manifest parameters, else 60; 0 disables)')
    p.add_argument('--label-voxel-m', type=float, default=None,
                   help='de-duplication voxel of the union of truth clouds [m] (default: '
                   'label_voxel_m of sessions.yaml, else 0.1)')
    p.add_argument('--stamp-tolerance-s', type=float, default=1e-3,
                   help='stamp association tolerance [s] (default 0.001)')
    p.add_argument('--rpe-all-pairs', action='store_true',
                   help='RPE over all pairs (evo_rpe --all_pairs, tolerance 10%% of delta) '
                   'instead of consecutive ones')
    p.add_argument('--submap-origins', choices=('estimated', 'truth'), default='estimated',
                   help='where the dynamics part places each submap: its estimated origin '
                        '(default), or its true origin, which measures the content of the map '
                        '(what was removed and kept) without its alignment error (a diagnosis; '
                        'not a result of the pipeline)')
    p.add_argument('--dynamics-frame', choices=('map-fit', 'first-scan'), default='map-fit',
                   help='frame in which the map is compared with the labelled truth points: '
                   'map-fit (default): one SE(3) that best aligns the whole map (every '
                   'session\'s poses at once) with the truth, so that a rigid offset of the '
                   'whole map, which the ATE figures already count, is not also counted as '
                   'removed static points; first-scan: the first scan\'s frame '
                   '(frame.t_map_world)')
    p.add_argument('--no-dynamics', action='store_true', help='skip the dynamic-removal part')
    p.add_argument('--no-plots', action='store_true', help='do not write PNG plots')
    p.add_argument('--quiet', action='store_true', help='do not print the tables')
    return p


def find_parameter(parameters, name, prefer='submap'):
    """Value of key `name` in the manifest's nested parameters (None if absent or ambiguous).

    With several matches the one whose path mentions `prefer` wins.
    """
    found = []

    def walk(node, path):
        if isinstance(node, dict):
            for key, value in node.items():
                if key == name and isinstance(value, (int, float)):
                    found.append(('/'.join(path + [str(key)]), float(value)))
                walk(value, path + [str(key)])
        elif isinstance(node, list):
            for i, value in enumerate(node):
                walk(value, path + [str(i)])
    walk(parameters or {}, [])
    preferred = [v for p, v in found if prefer in p.lower()]
    if len(set(preferred)) == 1:
        return preferred[0]
    if not preferred and len(set(v for _, v in found)) == 1:
        return found[0][1]
    return None


def _t_map_world(map_dir, truth_trajectories):
    """Fixed transform world -> map: inverse of the truth pose of the map origin scan."""
    first = map_dir.session_names[0]
    submaps = map_dir.submaps_of(first)
    trajectory = truth_trajectories.get(first)
    if trajectory is None or len(trajectory) == 0:
        raise io.EvalInputError('no ground-truth trajectory for the first session %s' % first)
    if submaps:
        origin_submap = min(submaps, key=lambda s: (s.id, s.first_stamp))
        t_world_sensor = trajectory.lookup(origin_submap.first_stamp, 1e-3)
        if t_world_sensor is not None:
            # The map frame is the first scan's: its pose in the map is the identity by
            # construction (submap 0's origin times the scan's pose in it); divide it out anyway.
            t_map_sensor = origin_submap.origin @ origin_submap.first_scan_pose
            return tr.inverse(t_world_sensor @ tr.inverse(t_map_sensor))
    return tr.inverse(trajectory.poses[0])


def t_map_world_fitted(map_dir, truth_map, t_map_world, tolerance_s):
    """World -> map through one SE(3) fit of the whole map: Umeyama on the positions of every
    session's poses at once (truth_map: truth already in the first scan's frame). The sessions
    are not aligned separately, so their offsets against each other stay in the figures. With
    fewer than 3 associated poses the first scan's transform is returned unchanged."""
    estimates, truths = [], []
    for name in map_dir.session_names:
        estimate = map_dir.trajectory(name)
        if estimate is None or name not in truth_map:
            continue
        est, ref = tr.associate(estimate, truth_map[name], tolerance_s)
        estimates.append(est)
        truths.append(ref)
    if sum(len(e) for e in estimates) < 3:
        return t_map_world
    return tr.align_se3(np.concatenate(truths), np.concatenate(estimates)) @ t_map_world


def map_frames(map_dir, truth_world, tolerance_s):
    """(T_map_world of the first scan, T_map_world of the whole-map fit)."""
    first_scan = _t_map_world(map_dir, truth_world)
    truth_map = {n: t.transformed(first_scan) for n, t in truth_world.items()}
    return first_scan, t_map_world_fitted(map_dir, truth_map, first_scan, tolerance_s)


def _trajectory_figures(estimate, truth_map, truth_fit, odom, options, warnings, name):
    keys = {'ate_rmse_m': None, 'ate_mean_m': None, 'ate_median_m': None, 'ate_max_m': None,
            'ate_rmse_map_fit_m': None, 'ate_max_map_fit_m': None, 'ate_rmse_aligned_m': None,
            'ate_poses': 0, 'odom_ate_rmse_aligned_m': None,
            'rpe_10m_pct': None, 'rpe_10m_deg': None, 'rpe_10m_pairs': 0,
            'rpe_100m_pct': None, 'rpe_100m_deg': None, 'rpe_100m_pairs': 0,
            'rpe_100m_trans_rmse_m': None, 'path_length_m': None}
    if estimate is None:
        warnings.append('%s: no trajectories/%s.tum' % (name, name))
        return keys
    est, ref = tr.associate(estimate, truth_map, options.stamp_tolerance_s)
    if len(est) == 0:
        warnings.append('%s: no estimated pose matches a truth stamp' % name)
        return keys
    if len(est) < len(estimate):
        warnings.append('%s: %d of %d estimated poses have no truth stamp'
                        % (name, len(estimate) - len(est), len(estimate)))
    a = tr.ate(est, ref)
    fit = tr.ate(*tr.associate(estimate, truth_fit, options.stamp_tolerance_s))
    keys.update({'ate_rmse_m': a['rmse'], 'ate_mean_m': a['mean'], 'ate_median_m': a['median'],
                 'ate_max_m': a['max'], 'ate_poses': a['n'],
                 'ate_rmse_aligned_m': tr.ate(est, ref, align=True)['rmse'],
                 'ate_rmse_map_fit_m': fit['rmse'], 'ate_max_map_fit_m': fit['max'],
                 'path_length_m': tr.Trajectory(np.zeros(len(ref)), ref).path_length()})
    for delta, tag in ((10.0, '10m'), (100.0, '100m')):
        r = tr.rpe(est, ref, delta, all_pairs=options.rpe_all_pairs)
        keys['rpe_%s_pct' % tag] = r['pct']
        keys['rpe_%s_deg' % tag] = r['deg_per_100m']
        keys['rpe_%s_pairs' % tag] = r['pairs']
        if tag == '100m':
            keys['rpe_100m_trans_rmse_m'] = r['trans_m']['rmse']
    if odom is not None:
        e2, r2 = tr.associate(odom, truth_map, options.stamp_tolerance_s)
        if len(e2):
            keys['odom_ate_rmse_aligned_m'] = tr.ate(e2, r2, align=True)['rmse']
    return keys


def _offset_figures(pose):
    """Rotation angle [deg] and translation [m] of a rigid transform."""
    cos_angle = np.clip((np.trace(pose[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    return {'rotation_deg': float(np.degrees(np.arccos(cos_angle))),
            'translation_m': float(np.linalg.norm(pose[:3, 3]))}


def run(options):
    """Computes the report (a dict) and the data for the plots."""
    started = time.time()
    warnings = []
    map_dir = io.MapDir(options.map)
    truth = io.Truth(options.truth)
    if not map_dir.session_names:
        raise io.EvalInputError('%s/manifest.yaml lists no session' % options.map)
    truth_names = {}
    truth_world = {}
    for name in map_dir.session_names:
        resolved = truth.resolve(name)
        if resolved is None:
            raise io.EvalInputError('session %s of the map is not in %s/sessions.yaml'
                                    % (name, options.truth))
        truth_names[name] = resolved
        truth_world[name] = truth.trajectory(resolved)
    t_map_world, t_map_world_fit = map_frames(map_dir, truth_world, options.stamp_tolerance_s)
    truth_map = {n: t.transformed(t_map_world) for n, t in truth_world.items()}
    truth_fit = {n: t.transformed(t_map_world_fit) for n, t in truth_world.items()}
    # The dynamics part compares points in this frame.
    t_map_world_points = t_map_world_fit if options.dynamics_frame == 'map-fit' else t_map_world

    loop_options = loops.LoopOptions(options.loop_max_trans_m, options.loop_max_rot_deg,
                                     options.overlap_radius_m, options.overlap_min_fraction,
                                     options.stamp_tolerance_s)
    sessions = []
    timing_per_session = []
    pr_curves = {}
    est_positions = {}
    for index, name in enumerate(map_dir.session_names):
        entry = map_dir.sessions[index]
        estimate = map_dir.trajectory(name)
        odom_path = os.path.join(map_dir.path, 'trajectories', '%s_odom.tum' % name)
        odom = tr.read_tum(odom_path) if os.path.isfile(odom_path) else None
        s = {'name': name, 'truth_session': truth_names[name],
             'scans': int(entry.get('scans') or (len(estimate) if estimate else 0)),
             'duration_s': float(entry.get('duration_s') or
                                 (estimate.stamps[-1] - estimate.stamps[0]
                                  if estimate is not None and len(estimate) > 1 else 0.0)),
             'has_history': index > 0}
        s.update(_trajectory_figures(estimate, truth_map[name], truth_fit[name], odom, options,
                                     warnings, name))
        if estimate is not None:
            est_positions[name] = estimate.positions
        if index > 0 and not map_dir.has_loops(name):
            warnings.append('%s: no loops/%s.csv (all submaps counted as undefined)'
                            % (name, name))
        table = loops.session_table(map_dir, index, truth_world, loop_options)
        s['submap_status'] = table.pop('submap_status')
        if table['submaps_unknown'] or table['loops_unjudged']:
            warnings.append('%s: %d submaps and %d accepted loops could not be judged (submap '
                            'missing from the manifest or stamp missing from the truth)'
                            % (name, table['submaps_unknown'], table['loops_unjudged']))
        s.update(table)
        rows = map_dir.place_recognition(name) if index > 0 else None
        if index > 0 and rows is None:
            warnings.append('%s: no place_recognition/%s.csv (kept for the last '
                            'map_update.record_sessions sessions only)' % (name, name))
        history = {h: truth_world[h] for h in map_dir.session_names[:index]}
        pr = place_recognition.evaluate_session(rows, truth_world[name], history,
                                                options.pr_radius_m, options.pr_k,
                                                options.stamp_tolerance_s)
        pr_curves[name] = pr.pop('curve')
        s['place_recognition'] = pr
        record = map_dir.timing(name)
        if record is None:
            warnings.append('%s: no timing/%s.yaml' % (name, name))
        figures = timing.session_figures(record)
        timing_per_session.append(figures)
        s['timing'] = figures
        sessions.append(s)

    result = {'format': 'multisession_mapper_eval/1',
              'inputs': {'map': os.path.abspath(options.map),
                         'truth': os.path.abspath(options.truth),
                         'map_format_version': map_dir.format_version},
              'options': {k: v for k, v in vars(options).items()
                          if k not in ('map', 'truth', 'out')},
              'frame': {'t_map_world': tr.pose_to_list(t_map_world),
                        't_map_world_fit': tr.pose_to_list(t_map_world_fit),
                        'map_fit': _offset_figures(t_map_world_fit @ tr.inverse(t_map_world))},
              'sessions': sessions}

    plot_data = {'est_traj': est_positions,
                 'truth_traj': {n: t.positions for n, t in truth_map.items()},
                 'truth_map_traj': truth_map, 'truth_fit_traj': truth_fit,
                 'pr_curves': pr_curves, 'sessions': sessions[1:] or sessions,
                 'map_points': None, 'removed': None}
    needs_points = not options.no_dynamics or not options.no_plots
    map_points = {}
    truth_lookup = loops.TruthLookup(truth_world, options.stamp_tolerance_s)
    if needs_points:
        for name in map_dir.session_names:
            active = [sm for sm in map_dir.submaps_of(name) if sm.status == 'active']
            clouds = []
            for sm in active:
                if not os.path.isfile(sm.file):
                    warnings.append('missing submap file %s' % sm.file)
                elif options.submap_origins == 'truth':
                    true_origin = truth_lookup.origin(sm)
                    if true_origin is None:
                        warnings.append('no truth pose for submap %s/%d: left out'
                                        % (sm.session, sm.id))
                    else:
                        clouds.append(sm.load_points(t_map_world_points @ true_origin))
                else:
                    clouds.append(sm.load_points())
            map_points[name] = np.vstack(clouds) if clouds else np.zeros((0, 3))
        plot_data['map_points'] = map_points
        removed = [map_dir.removed_points(n) for n in map_dir.session_names]
        removed = [r for r in removed if r is not None]
        plot_data['removed'] = np.vstack(removed) if removed else None

    result['dynamics'] = {'evaluated': False, 'low': dynamics.scores(None, None),
                          'high': dynamics.scores(None, None),
                          'all_dynamic': dynamics.scores(None, None),
                          'static': {'sa': None}, 'canopy': {'sa': None}}
    if options.no_dynamics:
        result['dynamics']['reason'] = 'disabled by --no-dynamics'
    else:
        voxel = options.label_voxel_m
        if voxel is None:
            voxel = float(truth.index.get('label_voxel_m', 0.1))
        kept_radius = options.kept_radius_m
        if kept_radius is None:
            submap_voxel = find_parameter(map_dir.parameters, 'voxel_size_m')
            kept_radius = max(0.2, submap_voxel or 0.0)
        eval_range = options.eval_range_m
        if eval_range is None:
            eval_range = find_parameter(map_dir.parameters, 'max_point_range_m') or 60.0
        gt = dynamics.ground_truth(truth, map_dir.session_names, truth_names, truth_world,
                                   t_map_world_points, options.observe_radius_m, voxel,
                                   eval_range, options.observed_rule, options.footprint_margin_m,
                                   options.footprint_min_points)
        if gt is None:
            result['dynamics']['reason'] = 'no truth/<session>_labels.pcd'
            warnings.append('dynamics not evaluated: no labelled truth cloud')
        else:
            all_map = (np.vstack(list(map_points.values())) if map_points
                       else np.zeros((0, 3)))
            figures, kept = dynamics.evaluate(gt.points, gt.labels, gt.category, all_map,
                                              kept_radius, options.kept_rule, gt.all_points,
                                              gt.all_category)
            figures['breakdown'] = dynamics.breakdown(gt.category, kept, gt.path_distance,
                                                      gt.object_ids, gt.low_presence,
                                                      labels=gt.labels)
            figures['evaluated'] = True
            figures['eval_range_m'] = eval_range
            figures['points']['outside_eval_range'] = gt.excluded
            figures['observed_rule'] = options.observed_rule
            figures['observe_radius_m'] = options.observe_radius_m
            figures['submap_origins'] = options.submap_origins
            figures['frame'] = options.dynamics_frame
            figures['label_voxel_m'] = voxel
            result['dynamics'] = figures

    result['map'] = map_stats.compute(map_dir)
    # Growth curve: only if the pipeline recorded the map size after each merge (optional).
    growth = [s['map_bytes_after_merge'] for s in timing_per_session]
    result['map']['bytes_after_session'] = [None if g is None else int(g) for g in growth]
    result['timing'] = timing.combine(timing_per_session)
    result['warnings'] = warnings
    result['evaluation_time_s'] = time.time() - started
    return result, plot_data


def main(argv=None):
    options = build_parser().parse_args(argv)
    out_dir = options.out or (os.path.normpath(options.map) + '_report')
    try:
        result, plot_data = run(options)
    except (io.EvalInputError, ValueError) as error:
        sys.stderr.write('evaluate: error: %s\n' % error)
        return 2
    if not options.no_plots:
        os.makedirs(out_dir, exist_ok=True)
        from . import plots  # matplotlib only when plotting
        result['plots'] = plots.write_all(out_dir, plot_data)
    # Truth in the map frame as TUM, so that users can run evo on the same pair of files.
    truth_dir = os.path.join(out_dir, 'truth_map_frame')
    os.makedirs(truth_dir, exist_ok=True)
    for name, trajectory in plot_data['truth_map_traj'].items():
        tr.write_tum(os.path.join(truth_dir, name + '.tum'), trajectory)
    fit_dir = os.path.join(out_dir, 'truth_map_fit')
    os.makedirs(fit_dir, exist_ok=True)
    for name, trajectory in plot_data['truth_fit_traj'].items():
        tr.write_tum(os.path.join(fit_dir, name + '.tum'), trajectory)
    text = report_mod.write(result, out_dir)
    if not options.quiet:
        print(text)
        print('\nreport written to %s' % os.path.abspath(out_dir))
    return 0


if __name__ == '__main__':
    sys.exit(main())
