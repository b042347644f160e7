"""Trajectories: TUM io, SE(3) helpers, Umeyama alignment, ATE and RPE (evo's definitions).

Definitions follow the `evo` package (Grupp, https://github.com/MichaelGrupp/evo):
- APE/ATE (translation part): e_i = || t(Q_i^-1 P_i) || after aligning the estimate P to the
  reference Q; RMSE, mean, median, max over the associated poses.
- RPE: E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) for index pairs (i, j) chosen by travelled path:
  evo's default (all_pairs=False) walks the estimate from index 0, accumulates the path length
  and emits an index each time it reaches `delta` metres, then pairs consecutive indices. The
  translation error is || t(E_ij) ||, the rotation error the angle of R(E_ij).
  (Checked against evo 1.38.1 on a noisy 900 m trajectory: identical ATE/RPE figures.) Percentages
  (KITTI style) are mean translation error / delta * 100, degrees per 100 m are mean angle /
  delta * 100.
- Umeyama (1991) least-squares similarity/rigid alignment of corresponding positions.
"""

import numpy as np


# ---------------------------------------------------------------------------------------------
# SE(3) helpers (4x4 matrices)
# ---------------------------------------------------------------------------------------------
def quat_to_rot(q):
    """Rotation matrix from a quaternion (x, y, z, w); normalises the input."""
    x, y, z, w = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def rot_to_quat(r):
    """Quaternion (x, y, z, w) with w >= 0 from a rotation matrix."""
    m = np.asarray(r, dtype=np.float64)
    trace = np.trace(m)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i] = 0.25 * s
        q[j] = (m[j, i] + m[i, j]) / s
        q[k] = (m[k, i] + m[i, k]) / s
    q = np.array(q)
    return q if q[3] >= 0 else -q


def pose_from_list(values):
    """4x4 pose from [tx, ty, tz, qx, qy, qz, qw]."""
    values = np.asarray(values, dtype=np.float64)
    pose = np.eye(4)
    pose[:3, :3] = quat_to_rot(values[3:7])
    pose[:3, 3] = values[:3]
    return pose


def pose_to_list(pose):
    return [float(v) for v in list(pose[:3, 3]) + list(rot_to_quat(pose[:3, :3]))]


def inverse(pose):
    inv = np.eye(4)
    inv[:3, :3] = pose[:3, :3].T
    inv[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return inv


def rotation_angle_rad(r):
    """Angle of a rotation matrix in [0, pi]."""
    return float(np.arccos(np.clip((np.trace(r[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)))


def relative_error(estimate, truth):
    """(translation error [m], rotation error [deg]) of a relative pose against its truth."""
    error = inverse(truth) @ estimate
    return float(np.linalg.norm(error[:3, 3])), float(np.degrees(rotation_angle_rad(error)))


def transform_points(pose, points):
    return points @ pose[:3, :3].T + pose[:3, 3]


# ---------------------------------------------------------------------------------------------
# TUM files
# ---------------------------------------------------------------------------------------------
class Trajectory(object):
    """Stamps (N,) [s] and poses (N, 4, 4)."""

    def __init__(self, stamps, poses):
        self.stamps = np.asarray(stamps, dtype=np.float64)
        self.poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)

    def __len__(self):
        return len(self.stamps)

    @property
    def positions(self):
        return self.poses[:, :3, 3]

    def transformed(self, pose):
        """The trajectory with every pose left-multiplied by `pose` (a change of frame)."""
        return Trajectory(self.stamps, np.einsum('ij,njk->nik', pose, self.poses))

    def lookup(self, stamp, tolerance_s=1e-3):
        """Pose at an exact stamp (nearest within tolerance), or None."""
        if len(self.stamps) == 0:
            return None
        i = int(np.clip(np.searchsorted(self.stamps, stamp), 1, len(self.stamps) - 1)) \
            if len(self.stamps) > 1 else 0
        best = i if abs(self.stamps[i] - stamp) <= abs(self.stamps[i - 1] - stamp) else i - 1
        if abs(self.stamps[best] - stamp) > tolerance_s:
            return None
        return self.poses[best]

    def path_length(self):
        if len(self) < 2:
            return 0.0
        return float(np.sum(np.linalg.norm(np.diff(self.positions, axis=0), axis=1)))


def read_tum(path):
    rows = []
    with open(path) as f:
        for number, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith('#'):
                continue
            values = line.replace(',', ' ').split()
            if len(values) != 8:
                raise ValueError('%s:%d: expected 8 values, got %d' % (path, number, len(values)))
            rows.append([float(v) for v in values])
    rows = np.array(rows, dtype=np.float64).reshape(-1, 8)
    order = np.argsort(rows[:, 0], kind='stable')
    rows = rows[order]
    return Trajectory(rows[:, 0], [pose_from_list(r[1:]) for r in rows])


def write_tum(path, trajectory):
    with open(path, 'w') as f:
        for stamp, pose in zip(trajectory.stamps, trajectory.poses):
            f.write('%.9f %s\n' % (stamp, ' '.join('%.9f' % v for v in pose_to_list(pose))))


# ---------------------------------------------------------------------------------------------
# Association and alignment
# ---------------------------------------------------------------------------------------------
def associate(estimate, reference, tolerance_s=1e-3):
    """Pairs of poses with equal stamps (nearest within tolerance): (est_poses, ref_poses)."""
    if len(estimate) == 0 or len(reference) == 0:
        return np.zeros((0, 4, 4)), np.zeros((0, 4, 4))
    idx = np.clip(np.searchsorted(reference.stamps, estimate.stamps), 0, len(reference) - 1)
    prev = np.clip(idx - 1, 0, len(reference) - 1)
    choose_prev = (np.abs(reference.stamps[prev] - estimate.stamps)
                   < np.abs(reference.stamps[idx] - estimate.stamps))
    idx = np.where(choose_prev, prev, idx)
    ok = np.abs(reference.stamps[idx] - estimate.stamps) <= tolerance_s
    return estimate.poses[ok], reference.poses[idx[ok]]


def umeyama(source, target, with_scale=False):
    """R, t, s minimising sum || target - (s R source + t) ||^2 (Umeyama 1991)."""
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    xs, xt = source - mu_s, target - mu_t
    cov = xt.T @ xs / len(source)
    u, d, vt = np.linalg.svd(cov)
    sign = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[2, 2] = -1
    rot = u @ sign @ vt
    scale = 1.0
    if with_scale:
        var_s = np.mean(np.sum(xs ** 2, axis=1))
        scale = float(np.trace(np.diag(d) @ sign) / var_s)
    trans = mu_t - scale * rot @ mu_s
    return rot, trans, scale


def align_se3(est_poses, ref_poses):
    """4x4 transform T (rigid, Umeyama on positions) such that T * est ~ ref."""
    transform = np.eye(4)
    if len(est_poses) < 3:
        if len(est_poses) >= 1:  # translation only
            transform[:3, 3] = np.mean(ref_poses[:, :3, 3] - est_poses[:, :3, 3], axis=0)
        return transform
    rot, trans, _ = umeyama(est_poses[:, :3, 3], ref_poses[:, :3, 3])
    transform[:3, :3] = rot
    transform[:3, 3] = trans
    return transform


def _stats(errors):
    errors = np.asarray(errors, dtype=np.float64)
    if len(errors) == 0:
        return {'rmse': None, 'mean': None, 'median': None, 'max': None, 'std': None, 'n': 0}
    return {'rmse': float(np.sqrt(np.mean(errors ** 2))), 'mean': float(np.mean(errors)),
            'median': float(np.median(errors)), 'max': float(np.max(errors)),
            'std': float(np.std(errors)), 'n': int(len(errors))}


def ate(est_poses, ref_poses, align=False):
    """Translation APE statistics [m]; with align=True after Umeyama SE(3) alignment."""
    est_poses = np.asarray(est_poses)
    if align and len(est_poses):
        est_poses = np.einsum('ij,njk->nik', align_se3(est_poses, ref_poses), est_poses)
    errors = np.linalg.norm(est_poses[:, :3, 3] - np.asarray(ref_poses)[:, :3, 3], axis=1) \
        if len(est_poses) else []
    return _stats(errors)


def pairs_by_path(poses, delta_m):
    """evo's filter_pairs_by_path with all_pairs=False (consecutive, non-overlapping).

    As in evo 1.38: index 0, then every index where the path since the last one reaches delta.
    """
    if len(poses) == 0:
        return []
    ids = [0]
    path = 0.0
    for i in range(1, len(poses)):
        path += float(np.linalg.norm(poses[i][:3, 3] - poses[i - 1][:3, 3]))
        if path >= delta_m:
            ids.append(i)
            path = 0.0
    return list(zip(ids, ids[1:]))


def pairs_by_path_all(poses, delta_m, tolerance_m):
    """evo's all_pairs=True variant: every i with a j whose path distance is delta +- tol."""
    if len(poses) < 2:
        return []
    steps = np.linalg.norm(np.diff(np.asarray(poses)[:, :3, 3], axis=0), axis=1)
    distances = np.concatenate([[0.0], np.cumsum(steps)])
    pairs = []
    for i in range(len(distances) - 1):
        ahead = distances[i + 1:] - distances[i]
        k = int(np.argmin(np.abs(ahead - delta_m)))
        if abs(ahead[k] - delta_m) <= tolerance_m:
            pairs.append((i, i + 1 + k))
    return pairs


def rpe(est_poses, ref_poses, delta_m, all_pairs=False, tolerance_m=None):
    """RPE over pairs `delta_m` apart in travelled path (of the estimate, as evo by default).

    Returns translation stats [m], rotation stats [deg], and the KITTI-style normalised means
    `pct` (mean translation error / delta * 100) and `deg_per_100m`.
    """
    est_poses = np.asarray(est_poses)
    ref_poses = np.asarray(ref_poses)
    if all_pairs:
        pairs = pairs_by_path_all(est_poses, delta_m,
                                  0.1 * delta_m if tolerance_m is None else tolerance_m)
    else:
        pairs = pairs_by_path(est_poses, delta_m)
    trans, rot = [], []
    for i, j in pairs:
        rel_est = inverse(est_poses[i]) @ est_poses[j]
        rel_ref = inverse(ref_poses[i]) @ ref_poses[j]
        t_err, r_err = relative_error(rel_est, rel_ref)
        trans.append(t_err)
        rot.append(r_err)
    result = {'delta_m': float(delta_m), 'pairs': len(pairs), 'trans_m': _stats(trans),
              'rot_deg': _stats(rot), 'pct': None, 'deg_per_100m': None}
    if pairs:
        result['pct'] = float(np.mean(trans) / delta_m * 100.0)
        result['deg_per_100m'] = float(np.mean(rot) / delta_m * 100.0)
    return result
