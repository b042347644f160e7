#!/usr/bin/env python3
"""DUFOMap (Duberg et al., RA-L 2024) next to our map on the simulated sessions (issue 7).

Run by scripts/bench.d/dufomap.sh in the bench virtualenv (PyPI `dufomap`, `rosbags`).

1. Every scan of every session of DATA_DIR (sessions.yaml -> sessions[].bag, PointCloud2 on
   the lidar topic) is placed in the world frame with the simulator's truth trajectory
   (truth/<session>.tum = sensor pose in the world at the scan stamp). The simulator fires
   each column at its own time (point field `time`, seconds after the stamp) from the sensor
   pose of that moment, so each point is placed with the truth pose interpolated to its time
   (deskew; linear translation, constant angular rate between consecutive truth poses).
   A placement check reports the fraction of placed points within 0.1 m of the session's
   labelled truth cloud (world frame) for a few scans, with and without the deskew.
2. DUFOMap integrates all scans of all sessions (run(cloud, sensor origin,
   cloud_transform=False), as its authors' main.py does with world-frame clouds), propagates
   once and writes its static output cloud (outputMap, point level, no voxelisation).
3. That cloud is scored by the project's evaluator (multisession_mapper_eval.dynamics:
   ground_truth + evaluate, the arguments of cli.py). The cloud is in the world frame, so the
   ground truth is built with T_map_world = identity (the evaluator's "map frame" is then the
   world frame); the metrics only use distances between the two point sets, which are the same
   in any common frame. Our map (MAP_DIR, own SLAM poses) is scored in the same run with the
   transform cli.py uses for it (inverse truth pose of its first submap's first scan).
4. Two more views of DUFOMap's output: resampled to one centroid per voxel of the kept radius
   (as our map is, so that the radius rule treats both alike: in a dense output one point left
   of an object keeps its truth points), and DynamicMap's own per-point rule (every input point
   near a truth point is labelled by it and is kept or removed; the figures its benchmark
   publishes). Our map is resampled, so only the radius rule applies to it.

Ground truth is read here only for placing the scans and for scoring (benchmark code).
Writes a JSON file and prints a Markdown table.
"""

import argparse
import json
import os
import resource
import sys
import time

import numpy as np

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
sys.path.insert(0, os.path.join(REPO, 'python'))

from multisession_mapper_eval import cli as eval_cli  # noqa: E402
from multisession_mapper_eval import dynamics  # noqa: E402
from multisession_mapper_eval import io as eval_io  # noqa: E402
from multisession_mapper_eval import neighbors  # noqa: E402
from multisession_mapper_eval import pcd  # noqa: E402
from multisession_mapper_eval import timing  # noqa: E402
from multisession_mapper_eval import trajectory as tr  # noqa: E402

# sensor_msgs/PointField datatypes -> numpy (little-endian; '>' prefix for big-endian clouds)
_POINTFIELD_TYPES = {1: 'i1', 2: 'u1', 3: 'i2', 4: 'u2', 5: 'i4', 6: 'u4', 7: 'f4', 8: 'f8'}
FLOAT32 = 7


# ---------------------------------------------------------------------------------------------
# PointCloud2 decoding
# ---------------------------------------------------------------------------------------------
def cloud_arrays(data, fields, point_step, row_step, width, height, is_bigendian,
                 names=('x', 'y', 'z'), optional=('time',)):
    """Columns of a PointCloud2 as float arrays: {name: (N,) array}.

    fields: sequence of (name, offset, datatype, count). x, y, z (the `names`) must be FLOAT32
    with count 1; `optional` fields are returned when present (any numeric datatype). Rows
    may be padded (row_step > width * point_step). Raises ValueError on another layout.
    """
    layout = {str(f[0]): (int(f[1]), int(f[2]), int(f[3])) for f in fields}
    for name in names:
        if name not in layout:
            raise ValueError('PointCloud2 has no field %r (fields: %s)'
                             % (name, ', '.join(sorted(layout))))
        offset, datatype, count = layout[name]
        if datatype != FLOAT32 or count != 1:
            raise ValueError('field %r: datatype %d count %d, expected FLOAT32 (7) count 1'
                             % (name, datatype, count))
    wanted = list(names) + [n for n in optional if n in layout]
    order = '>' if is_bigendian else '<'
    dtype = np.dtype({'names': wanted,
                      'formats': [order + _POINTFIELD_TYPES[layout[n][1]] for n in wanted],
                      'offsets': [layout[n][0] for n in wanted],
                      'itemsize': int(point_step)})
    buf = np.frombuffer(bytes(data) if not isinstance(data, np.ndarray) else data.tobytes(),
                        dtype=np.uint8)
    if height * row_step > len(buf) or width * point_step > row_step:
        raise ValueError('PointCloud2 of %dx%d points (step %d, row %d) in %d bytes'
                         % (height, width, point_step, row_step, len(buf)))
    rows = buf[:height * row_step].reshape(height, row_step)[:, :width * point_step]
    records = np.ascontiguousarray(rows).reshape(-1).view(dtype)
    return {n: records[n].astype(np.float64) for n in wanted}


def read_bag_scans(bag_path, topic):
    """Yields (stamp [s], points (N, 3) float64 sensor frame, times (N,) or None) per scan."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_typestore
    typestore = get_typestore(Stores.ROS1_NOETIC)
    with Reader(bag_path) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        if not connections:
            raise ValueError('%s: no topic %s' % (bag_path, topic))
        for connection, _, raw in reader.messages(connections=connections):
            msg = typestore.deserialize_ros1(raw, connection.msgtype)
            fields = [(f.name, f.offset, f.datatype, f.count) for f in msg.fields]
            columns = cloud_arrays(msg.data, fields, msg.point_step, msg.row_step, msg.width,
                                   msg.height, msg.is_bigendian)
            points = np.column_stack([columns['x'], columns['y'], columns['z']])
            finite = np.all(np.isfinite(points), axis=1)
            times = columns.get('time')
            stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            yield stamp, points[finite], (times[finite] if times is not None else None)


# ---------------------------------------------------------------------------------------------
# Placement with the truth poses (deskew)
# ---------------------------------------------------------------------------------------------
def rotation_log(r):
    """Rotation vector (axis * angle) of a 3x3 rotation matrix."""
    r = np.asarray(r, dtype=np.float64)
    angle = tr.rotation_angle_rad(r)
    skew = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-9:
        return 0.5 * skew
    if np.pi - angle < 1e-6:  # half turn: axis from the symmetric part
        axis = np.sqrt(np.maximum((np.diag(r) + 1.0) / 2.0, 0.0))
        i = int(np.argmax(axis))
        axis = (r[:, i] + np.eye(3)[:, i]) / (2.0 * axis[i])
        return angle * axis / np.linalg.norm(axis)
    return angle / (2.0 * np.sin(angle)) * skew


def rotate_by_rotvecs(rotvecs, vectors):
    """Rotates each vectors[i] by the rotation vector rotvecs[i] (Rodrigues), (N, 3)."""
    rotvecs = np.asarray(rotvecs, dtype=np.float64).reshape(-1, 3)
    vectors = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
    angle = np.linalg.norm(rotvecs, axis=1)
    safe = np.where(angle > 1e-12, angle, 1.0)
    axis = rotvecs / safe[:, None]
    cos, sin = np.cos(angle)[:, None], np.sin(angle)[:, None]
    dot = np.sum(axis * vectors, axis=1)[:, None]
    return vectors * cos + np.cross(axis, vectors) * sin + axis * dot * (1.0 - cos)


def scan_pose_pair(trajectory, index):
    """(pose at stamp[index], pose at stamp[index + 1], time step [s]).

    The last pose of the trajectory has no successor: the previous step's motion is repeated
    (constant velocity); a one-pose trajectory gives no motion (and a step of 0.1 s).
    """
    stamps, poses = trajectory.stamps, trajectory.poses
    if index + 1 < len(stamps):
        return poses[index], poses[index + 1], float(stamps[index + 1] - stamps[index])
    if index >= 1:
        step = tr.inverse(poses[index - 1]) @ poses[index]
        return poses[index], poses[index] @ step, float(stamps[index] - stamps[index - 1])
    return poses[index], poses[index], 0.1


def place_points(points, times, pose0, pose1, dt):
    """Sensor-frame points -> world frame, each at its own time (deskew).

    pose0, pose1: sensor poses (4x4, world frame) at the scan stamp and dt seconds later;
    times: seconds after the stamp per point (None: every point at the stamp). Translation is
    interpolated linearly, rotation at a constant rate (R0 exp(alpha log(R0^T R1))); alpha > 1
    extrapolates.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if times is None or dt <= 0:
        return tr.transform_points(pose0, points)
    alpha = np.asarray(times, dtype=np.float64).reshape(-1) / dt
    rotvec = rotation_log(pose0[:3, :3].T @ pose1[:3, :3])
    local = rotate_by_rotvecs(alpha[:, None] * rotvec[None, :], points)
    translation = pose0[:3, 3][None, :] + alpha[:, None] * (pose1[:3, 3] - pose0[:3, 3])[None, :]
    return local @ pose0[:3, :3].T + translation


def dufomap_pose(pose):
    """DUFOMap's 7-value pose [x, y, z, qw, qx, qy, qz] from a 4x4 matrix."""
    x, y, z, qx, qy, qz, qw = tr.pose_to_list(pose)
    return [x, y, z, qw, qx, qy, qz]


# ---------------------------------------------------------------------------------------------
# Reporting
# ---------------------------------------------------------------------------------------------
def _pct(value):
    return '-' if value is None else '%.1f' % (100.0 * value)


def _num(value, fmt):
    return '-' if value is None else fmt % value


def markdown_table(rows):
    """Markdown table of the compared methods.

    rows: dicts with name, poses, static_sa, low_da, high_da, canopy_sa (ratios or None),
    map_points, time_s, peak_rss_mb (None prints '-').
    """
    lines = ['| method | poses | static SA % | low-dyn DA % | high-dyn DA % | canopy SA % '
             '| map points | time [s] | peak RSS [MB] |',
             '|---|---|---:|---:|---:|---:|---:|---:|---:|']
    for row in rows:
        lines.append('| %s | %s | %s | %s | %s | %s | %s | %s | %s |' % (
            row['name'], row['poses'], _pct(row.get('static_sa')), _pct(row.get('low_da')),
            _pct(row.get('high_da')), _pct(row.get('canopy_sa')),
            _num(row.get('map_points'), '%d'), _num(row.get('time_s'), '%.1f'),
            _num(row.get('peak_rss_mb'), '%.0f')))
    return '\n'.join(lines)


def table_row(name, poses, figures, time_s, peak_rss_mb):
    return {'name': name, 'poses': poses,
            'static_sa': figures['static']['sa'], 'low_da': figures['low']['da'],
            'high_da': figures['high']['da'], 'canopy_sa': figures['canopy']['sa'],
            'map_points': figures['points']['map'], 'time_s': time_s,
            'peak_rss_mb': peak_rss_mb}


def peak_rss_mb():
    """Peak resident set size of this process so far [MB] (Linux: ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def point_keys(points, step_m=0.001):
    """One int64 per point: its coordinates on a step_m grid (21 bits each, |coordinate| below
    about 1000 m at 1 mm). DUFOMap's output points are copies of input points, so equal keys
    find them among the input (two input points in one millimetre cell share a key)."""
    q = np.round(np.asarray(points, dtype=np.float64).reshape(-1, 3) / step_m).astype(np.int64)
    half = 1 << 20
    if len(q) and (q.min() < -half or q.max() >= half):
        raise ValueError('point_keys: a coordinate beyond %.0f m' % (half * step_m))
    q += half
    return (q[:, 0] << 42) | (q[:, 1] << 21) | q[:, 2]


def voxel_centroids(points, voxel_m):
    """The centroid of the points of each occupied voxel of edge voxel_m."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        return points
    cells = np.floor(points / voxel_m).astype(np.int64)
    _, inverse = np.unique(cells, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    counts = np.bincount(inverse).astype(np.float64)
    return np.stack([np.bincount(inverse, weights=points[:, k]) / counts for k in range(3)],
                    axis=1)


def per_point_figures(category, labels, kept):
    """DynamicMap's per-point figures of a method whose output is a subset of its input.

    category, labels: per labelled input point (dynamics.STATIC / LOW / HIGH, simulator class);
    kept: whether the point is in the output. SA = static kept / static, DA = dynamic removed /
    dynamic (None without such points)."""
    category, labels, kept = np.asarray(category), np.asarray(labels), np.asarray(kept, bool)

    def share(mask, value):
        n = int(np.sum(mask))
        return (None if n == 0 else float(np.sum(kept[mask] == value)) / n), n

    static = category == dynamics.STATIC
    sa, n_static = share(static, True)
    low_da, n_low = share(category == dynamics.LOW, False)
    high_da, n_high = share(category == dynamics.HIGH, False)
    canopy_sa, n_canopy = share(static & (labels == dynamics.CANOPY_CLASS), True)
    return {'static': {'sa': sa}, 'low': {'da': low_da}, 'high': {'da': high_da},
            'canopy': {'sa': canopy_sa},
            'points': {'static': n_static, 'low': n_low, 'high': n_high, 'canopy': n_canopy,
                       'map': int(np.sum(kept))}}


# ---------------------------------------------------------------------------------------------
# The run
# ---------------------------------------------------------------------------------------------
def placement_check(truth, session, trajectory, scans, radius_m=0.1):
    """Fraction of placed points within radius_m of the session's labelled truth cloud.

    scans: list of (index, points, times). Returns {'deskewed': f, 'stamp_pose_only': f,
    'scans': [...]} or None without a label cloud.
    """
    loaded = truth.labels(session)
    if loaded is None or not scans:
        return None
    reference = loaded[0]
    near = {'deskewed': [], 'stamp_pose_only': []}
    for index, points, times in scans:
        pose0, pose1, dt = scan_pose_pair(trajectory, index)
        for key, ts in (('deskewed', times), ('stamp_pose_only', None)):
            placed = place_points(points, ts, pose0, pose1, dt)
            near[key].append(neighbors.has_neighbor_within(reference, placed, radius_m))
    return {'radius_m': radius_m, 'scans': [s[0] for s in scans],
            'deskewed': float(np.mean(np.concatenate(near['deskewed']))),
            'stamp_pose_only': float(np.mean(np.concatenate(near['stamp_pose_only'])))}


def run_dufomap(truth, data_dir, topic, options, scratch):
    """Integrates every scan; returns (static cloud (N, 3), figures dict)."""
    from dufomap import dufomap, __version__ as dufomap_version
    mapper = dufomap(options.resolution, options.d_s, options.d_p,
                     num_threads=options.threads)
    accumulated = []
    read_wall = integrate_wall = 0.0
    integrate_cpu = 0.0
    checks = {}
    scans = 0
    for session in truth.session_names:
        entry = truth.sessions[session]
        trajectory = truth.trajectory(session)
        lookup = {round(float(s), 4): i for i, s in enumerate(trajectory.stamps)}
        check_scans = []
        started = time.time()
        for stamp, points, times in read_bag_scans(os.path.join(data_dir, entry['bag']), topic):
            index = lookup.get(round(stamp, 4))
            if index is None:
                raise ValueError('%s: scan stamp %.6f has no truth pose' % (session, stamp))
            pose0, pose1, dt = scan_pose_pair(trajectory, index)
            world = place_points(points, None if options.no_deskew else times, pose0, pose1, dt)
            world = np.ascontiguousarray(world, dtype=np.float32)
            if index % options.check_every == 0 and len(check_scans) < 5:
                check_scans.append((index, points, times))
            read_wall += time.time() - started
            cpu0, wall0 = time.process_time(), time.time()
            mapper.run(world, dufomap_pose(pose0), cloud_transform=False)
            integrate_cpu += time.process_time() - cpu0
            integrate_wall += time.time() - wall0
            accumulated.append(world)
            scans += 1
            started = time.time()
        checks[session] = placement_check(truth, session, trajectory, check_scans)
        sys.stderr.write('dufomap: %s integrated (%d scans so far, %.1f s)\n'
                         % (session, scans, integrate_wall))
    cloud = np.concatenate(accumulated) if accumulated else np.zeros((0, 3), np.float32)
    del accumulated
    cpu0, wall0 = time.process_time(), time.time()
    mapper.oncePropagateCluster(if_propagate=True, if_cluster=False)
    base = os.path.join(scratch, 'dufomap_output')
    mapper.outputMap(cloud, voxel_map=False, file_name=base)
    output_cpu, output_wall = time.process_time() - cpu0, time.time() - wall0
    rss = peak_rss_mb()
    path = base + '.pcd'
    if not os.path.isfile(path):
        raise RuntimeError('DUFOMap wrote no %s' % path)
    static = pcd.xyz(pcd.read_pcd(path))
    figures = {
        'version': dufomap_version,
        'parameters': {'resolution_m': options.resolution, 'inflate_hits_dist_m (d_s)': options.d_s,
                       'inflate_unknown (d_p)': options.d_p, 'num_threads': options.threads,
                       'hit_extension': True, 'ray_passthrough_hits': False,
                       'propagate': True, 'cluster': False, 'voxel_map_output': False,
                       'deskew_with_truth': not options.no_deskew},
        'scans': scans, 'input_points': int(len(cloud)), 'static_points': int(len(static)),
        'output_pcd': os.path.basename(path),
        'time_s': {'read_and_place': read_wall, 'integrate': integrate_wall,
                   'propagate_and_output': output_wall,
                   'dufomap_total': integrate_wall + output_wall},
        'cpu_s': {'integrate': integrate_cpu, 'propagate_and_output': output_cpu,
                  'dufomap_total': integrate_cpu + output_cpu},
        'ms_per_scan': 1000.0 * integrate_wall / scans if scans else None,
        'peak_rss_mb': rss,
        'placement_check': checks,
    }
    return static, cloud, figures


def score(truth, map_names, t_map_world, map_points, kept_radius, eval_range, options):
    """The evaluator's dynamics figures of `map_points` (frame given by t_map_world)."""
    truth_names = {n: n for n in map_names}
    truth_world = {n: truth.trajectory(n) for n in map_names}
    voxel = float(truth.index.get('label_voxel_m', 0.1))
    gt = dynamics.ground_truth(truth, map_names, truth_names, truth_world, t_map_world,
                               options.observe_radius_m, voxel, eval_range, 'footprint',
                               0.3, 5)
    if gt is None:
        raise ValueError('no labelled truth cloud in %s' % truth.path)
    figures, _ = dynamics.evaluate(gt.points, gt.labels, gt.category, map_points, kept_radius,
                                   'same_category', gt.all_points, gt.all_category)
    figures['eval_range_m'] = eval_range
    figures['label_voxel_m'] = voxel
    figures['points']['outside_eval_range'] = gt.excluded
    figures['t_map_world'] = tr.pose_to_list(t_map_world)
    return figures, gt


def score_per_point(gt, cloud, static, label_radius_m=0.15):
    """DynamicMap's rule for DUFOMap: every input point (world frame) takes the category and
    class of its nearest ground-truth point within label_radius_m (gt built with the identity,
    so also restricted to the evaluation range; farther points are not scored) and counts as
    kept when it is in DUFOMap's output `static`."""
    index = neighbors.nearest_within(gt.points, cloud, label_radius_m)
    labelled = index >= 0
    kept = np.isin(point_keys(cloud[labelled]), point_keys(static))
    figures = per_point_figures(gt.category[index[labelled]], gt.labels[index[labelled]], kept)
    figures['points']['unlabelled_input'] = int(np.sum(~labelled))
    figures['label_radius_m'] = label_radius_m
    return figures


def our_map(map_path, truth):
    """(map directory, T_map_world, map points, timing) of our map directory, as cli.py."""
    map_dir = eval_io.MapDir(map_path)
    truth_world = {}
    for name in map_dir.session_names:
        resolved = truth.resolve(name)
        if resolved != name:
            raise ValueError('map session %s is not a session of %s' % (name, truth.path))
        truth_world[name] = truth.trajectory(name)
    # The evaluator's default frame for the dynamics (--dynamics-frame map-fit): one SE(3) fit
    # of the whole map, so that DUFOMap (truth poses) and our map are scored on their content.
    t_map_world = eval_cli.map_frames(map_dir, truth_world, 1e-3)[1]
    clouds = [sm.load_points() for n in map_dir.session_names for sm in map_dir.submaps_of(n)
              if sm.status == 'active' and os.path.isfile(sm.file)]
    points = np.vstack(clouds) if clouds else np.zeros((0, 3))
    times = timing.combine([timing.session_figures(map_dir.timing(n))
                            for n in map_dir.session_names])
    return map_dir, t_map_world, points, times


def build_parser():
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--data', required=True, help='simulator output (sessions.yaml)')
    p.add_argument('--map', help='our map directory (scored in the same run; optional)')
    p.add_argument('--json', required=True, help='output JSON file')
    p.add_argument('--scratch', required=True, help='folder for DUFOMap\'s output PCD')
    p.add_argument('--resolution', type=float, default=0.1, help='voxel size v [m] (0.1)')
    p.add_argument('--d-s', type=float, default=0.2, help='inflate_hits_dist d_s [m] (0.2)')
    p.add_argument('--d-p', type=int, default=1, help='inflate_unknown d_p (1)')
    p.add_argument('--threads', type=int, default=0, help='DUFOMap threads (0: its auto)')
    p.add_argument('--no-deskew', action='store_true',
                   help='place every point with the pose of the scan stamp')
    p.add_argument('--check-every', type=int, default=100,
                   help='placement check on every n-th scan (at most 5 per session)')
    p.add_argument('--kept-radius-m', type=float, default=None,
                   help='default: max(0.2, submap voxel_size_m of --map), as the evaluator')
    p.add_argument('--eval-range-m', type=float, default=None,
                   help='default: submap max_point_range_m of --map, else 60, as the evaluator')
    p.add_argument('--observe-radius-m', type=float, default=30.0)
    return p


def main(argv=None):
    options = build_parser().parse_args(argv)
    truth = eval_io.Truth(options.data)
    topic = str(truth.index.get('lidar_topic', '/velodyne_points'))
    os.makedirs(options.scratch, exist_ok=True)
    static, cloud, dufo = run_dufomap(truth, options.data, topic, options, options.scratch)

    parameters = eval_io.MapDir(options.map).parameters if options.map else {}
    kept_radius = options.kept_radius_m
    if kept_radius is None:
        kept_radius = max(0.2, eval_cli.find_parameter(parameters, 'voxel_size_m') or 0.0)
    eval_range = options.eval_range_m
    if eval_range is None:
        eval_range = eval_cli.find_parameter(parameters, 'max_point_range_m') or 60.0

    started = time.time()
    dufo['dynamics'], gt = score(truth, truth.session_names, np.eye(4), static, kept_radius,
                                 eval_range, options)
    # Our rule favours a map resampled like ours: one point left of a car in DUFOMap's dense
    # output keeps the car's truth points within kept_radius. Two more views of the same output:
    # resampled to one centroid per submap voxel (as our map), and DynamicMap's own per-point rule.
    centroids = voxel_centroids(static, kept_radius)
    dufo['dynamics_voxel_centroids'], _ = score(truth, truth.session_names, np.eye(4), centroids,
                                                kept_radius, eval_range, options)
    dufo['dynamics_per_point'] = score_per_point(gt, cloud, static)
    del cloud
    name = 'DUFOMap %s' % dufo['version']
    rows = [table_row(name, 'truth', dufo['dynamics'], dufo['time_s']['dufomap_total'],
                      dufo['peak_rss_mb']),
            table_row(name + ', %.1f m voxel centroids' % kept_radius, 'truth',
                      dufo['dynamics_voxel_centroids'], None, None),
            table_row(name + ', per point (DynamicMap rule)', 'truth',
                      dufo['dynamics_per_point'], None, None)]
    result = {'format': 'multisession_mapper_bench_dufomap/1',
              'data': os.path.basename(os.path.normpath(options.data)),
              'sessions': truth.session_names, 'kept_radius_m': kept_radius,
              'eval_range_m': eval_range, 'dufomap': dufo}
    if options.map:
        map_dir, t_map_world, points, times = our_map(options.map, truth)
        ours = {'sessions': map_dir.session_names, 'timing': times,
                'dynamics': score(truth, map_dir.session_names, t_map_world, points,
                                  kept_radius, eval_range, options)[0]}
        if map_dir.session_names != truth.session_names:
            ours['warning'] = 'the map holds sessions %s, DATA_DIR %s' % (
                map_dir.session_names, truth.session_names)
        result['multisession_mapper'] = ours
        rows.append(table_row('multisession_mapper', 'own SLAM', ours['dynamics'],
                              times['wall_time_s_total'], times['peak_rss_mb']))
    result['evaluation_time_s'] = time.time() - started
    result['table'] = rows
    with open(options.json, 'w') as f:
        json.dump(result, f, indent=1)
    print(markdown_table(rows))
    print('\nDUFOMap %s: v=%.2f m, d_s=%.2f m, d_p=%d, %d threads, %d scans, %.1f ms/scan '
          '(integration wall), CPU %.1f s; time = integration + propagation + output '
          '(not the bag reading, %.1f s); peak RSS of the process before scoring (holds the '
          'accumulated input cloud, %d points).'
          % (dufo['version'], options.resolution, options.d_s, options.d_p, options.threads,
             dufo['scans'], dufo['ms_per_scan'] or 0.0, dufo['cpu_s']['dufomap_total'],
             dufo['time_s']['read_and_place'], dufo['input_points']))
    print('Rows 1-2 use the evaluator\'s rule (a truth point is kept when the map has a point of '
          'its category within %.2f m); row 3 scores every input point within %.2f m of a truth '
          'point by whether DUFOMap\'s output holds it (%d input points not scored).'
          % (kept_radius, dufo['dynamics_per_point']['label_radius_m'],
             dufo['dynamics_per_point']['points']['unlabelled_input']))
    if options.map:
        print('multisession_mapper: time = sum of its mapping runs\' wall times, peak RSS = '
              'their maximum (timing/*.yaml of MAP_DIR, not this run); scored in its map '
              'frame, DUFOMap in the world frame (T_map_world = identity).')
    for session, check in dufo['placement_check'].items():
        if check:
            print('placement check %s: %.1f %% of points within %.2f m of the truth cloud '
                  '(deskewed), %.1f %% with the stamp pose only'
                  % (session, 100 * check['deskewed'], check['radius_m'],
                     100 * check['stamp_pose_only']))
    return 0


if __name__ == '__main__':
    sys.exit(main())
