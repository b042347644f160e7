import math

import numpy as np
import pytest

from multisession_mapper_eval import trajectory as tr


def _pose(x, y, z, yaw=0.0, roll=0.0):
    p = np.eye(4)
    cz, sz, cr, sr = math.cos(yaw), math.sin(yaw), math.cos(roll), math.sin(roll)
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    p[:3, :3] = rz @ rx
    p[:3, 3] = [x, y, z]
    return p


def _curve(n=200, seed=0):
    rng = np.random.default_rng(seed)
    poses, x, y, yaw = [], 0.0, 0.0, 0.0
    for _ in range(n):
        yaw += rng.normal(0, 0.05)
        x += math.cos(yaw)
        y += math.sin(yaw)
        poses.append(_pose(x, y, 0.1 * math.sin(x / 10), yaw, rng.normal(0, 0.02)))
    return np.array(poses)


def test_quaternion_round_trip():
    rng = np.random.default_rng(7)
    for _ in range(50):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        q = q if q[3] >= 0 else -q
        np.testing.assert_allclose(tr.rot_to_quat(tr.quat_to_rot(q)), q, atol=1e-12)
    # 90 deg about z: (0, 0, sin 45, cos 45)
    r = tr.quat_to_rot([0, 0, math.sqrt(0.5), math.sqrt(0.5)])
    np.testing.assert_allclose(r @ [1, 0, 0], [0, 1, 0], atol=1e-12)


def test_tum_round_trip(tmp_path):
    poses = _curve(30)
    t = tr.Trajectory(100.0 + 0.1 * np.arange(30), poses)
    path = str(tmp_path / 't.tum')
    tr.write_tum(path, t)
    back = tr.read_tum(path)
    np.testing.assert_allclose(back.stamps, t.stamps)
    np.testing.assert_allclose(back.poses, t.poses, atol=1e-8)
    assert back.lookup(100.5) is not None and back.lookup(100.55) is None


def test_known_offset_gives_known_ate():
    ref = _curve()
    est = ref.copy()
    est[:, :3, 3] += [0.3, -0.4, 0.0]  # 0.5 m everywhere
    a = tr.ate(est, ref)
    assert a['rmse'] == pytest.approx(0.5) and a['max'] == pytest.approx(0.5)
    assert tr.ate(est, ref, align=True)['rmse'] == pytest.approx(0.0, abs=1e-9)


def test_alternating_offset_ate_statistics():
    ref = _curve(100)
    est = ref.copy()
    est[::2, :3, 3] += [0, 0, 1.0]   # half the poses 1 m off, half exact
    a = tr.ate(est, ref)
    assert a['rmse'] == pytest.approx(math.sqrt(0.5))
    assert a['mean'] == pytest.approx(0.5) and a['max'] == pytest.approx(1.0)


def test_umeyama_removes_known_rotation_and_translation():
    ref = _curve()
    transform = _pose(5.0, -3.0, 2.0, yaw=0.7, roll=0.1)
    est = np.einsum('ij,njk->nik', tr.inverse(transform), ref)
    assert tr.ate(est, ref)['rmse'] > 1.0
    aligned = tr.align_se3(est, ref)
    np.testing.assert_allclose(aligned, transform, atol=1e-9)
    assert tr.ate(est, ref, align=True)['rmse'] == pytest.approx(0.0, abs=1e-9)
    rot, trans, scale = tr.umeyama(ref[:, :3, 3] * 0.5, ref[:, :3, 3], with_scale=True)
    assert scale == pytest.approx(2.0)


def test_rpe_pairs_follow_evo():
    line = np.array([_pose(float(i), 0, 0) for i in range(301)])
    # evo 1.38: index 0, then where the accumulated path reaches delta; consecutive pairs.
    assert tr.pairs_by_path(line, 100.0) == [(0, 100), (100, 200), (200, 300)]
    assert tr.pairs_by_path(line, 1000.0) == []
    pairs = tr.pairs_by_path_all(line, 100.0, 0.5)
    assert pairs[0] == (0, 100) and len(pairs) == 201


def test_rpe_known_scale_drift():
    ref = np.array([_pose(float(i), 0, 0) for i in range(301)])
    est = np.array([_pose(1.01 * i, 0, 0) for i in range(301)])
    r = tr.rpe(est, ref, 100.0)
    # estimate steps 1.01 m: ids 0, 100, 200, 300 (99 steps are 99.99 m); each pair 100 m of
    # truth, 101 m estimated.
    assert r['pairs'] == 3
    assert r['pct'] == pytest.approx(1.0)
    assert r['deg_per_100m'] == pytest.approx(0.0, abs=1e-9)
    assert r['trans_m']['rmse'] == pytest.approx(1.0)


def test_rpe_known_heading_drift():
    ref = np.array([_pose(float(i), 0, 0) for i in range(301)])
    est = np.array([_pose(float(i), 0, 0, yaw=math.radians(0.01 * i)) for i in range(301)])
    r = tr.rpe(est, ref, 100.0)
    assert r['pairs'] == 3
    assert r['deg_per_100m'] == pytest.approx(1.0)
    assert r['rot_deg']['max'] == pytest.approx(1.0)


def test_rpe_invariant_to_global_transform():
    ref = _curve(300)
    est = np.einsum('ij,njk->nik', _pose(10, 20, 3, 1.0), ref)
    r = tr.rpe(est, ref, 10.0)
    assert r['pairs'] > 10
    assert r['trans_m']['max'] == pytest.approx(0.0, abs=1e-9)


def test_associate_by_stamp():
    ref = tr.Trajectory(np.arange(10) * 0.1, _curve(10))
    est = tr.Trajectory(np.array([0.1, 0.3, 0.35, 0.9005]), _curve(4, seed=1))
    e, r = tr.associate(est, ref, 1e-3)
    assert len(e) == 3   # 0.35 has no truth within 1 ms
    np.testing.assert_allclose(r[2], ref.poses[9])


def test_relative_error():
    t, r = tr.relative_error(_pose(1, 0, 0, yaw=math.radians(2)), _pose(1, 0.3, 0))
    assert t == pytest.approx(0.3) and r == pytest.approx(2.0)


def _evo_case(tmp_path):
    """The noisy 900 m trajectory pair that was run through evo 1.38.1 (values below)."""
    rng = np.random.default_rng(3)

    def pose(x, y, z, yaw, roll=0.0, pitch=0.0):
        p = np.eye(4)
        cz, sz = math.cos(yaw), math.sin(yaw)
        cr, sr = math.cos(roll), math.sin(roll)
        cp, sp = math.cos(pitch), math.sin(pitch)
        p[:3, :3] = (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
                     @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
                     @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))
        p[:3, 3] = [x, y, z]
        return p
    n, x, y, yaw = 3000, 0.0, 0.0, 0.0
    ref, est = [], []
    for i in range(n):
        yaw += rng.normal(0, 0.02)
        step = 0.3 + 0.05 * math.sin(i / 50)
        x += step * math.cos(yaw)
        y += step * math.sin(yaw)
        ref.append(pose(x, y, 0.5 * math.sin(x / 30), yaw, rng.normal(0, 0.01),
                        rng.normal(0, 0.01)))
        est_yaw = yaw + 0.0001 * i + rng.normal(0, 0.002)
        est.append(pose(x * 1.003 + rng.normal(0, 0.02), y + rng.normal(0, 0.02) + 0.0002 * i,
                        0.5 * math.sin(x / 30) + rng.normal(0, 0.02), est_yaw))
    stamps = 100 + 0.1 * np.arange(n)
    # Through TUM files, as evo read them (9 decimals).
    tr.write_tum(str(tmp_path / 'ref.tum'), tr.Trajectory(stamps, ref))
    tr.write_tum(str(tmp_path / 'est.tum'), tr.Trajectory(stamps, est))
    est_back = tr.read_tum(str(tmp_path / 'est.tum'))
    return est_back.poses, tr.read_tum(str(tmp_path / 'ref.tum')).poses


def test_figures_equal_evo(tmp_path):
    # Reference values printed by evo 1.38.1 on the same two files:
    #   evo_ape tum ref.tum est.tum [-a];
    #   evo_rpe tum ref.tum est.tum --delta D --delta_unit m [--all_pairs] [-r angle_deg]
    est, ref = _evo_case(tmp_path)
    rel = dict(rel=2e-6)
    assert tr.ate(est, ref)['rmse'] == pytest.approx(1.428149, **rel)
    assert tr.ate(est, ref)['mean'] == pytest.approx(1.245692, **rel)
    assert tr.ate(est, ref, align=True)['rmse'] == pytest.approx(0.680854, **rel)
    r10 = tr.rpe(est, ref, 10.0)
    assert r10['pairs'] == 90
    assert r10['trans_m']['rmse'] == pytest.approx(1.726624, **rel)
    assert r10['trans_m']['mean'] == pytest.approx(1.495594, **rel)
    assert r10['rot_deg']['rmse'] == pytest.approx(1.230219, **rel)
    assert r10['rot_deg']['mean'] == pytest.approx(1.124385, **rel)
    r100 = tr.rpe(est, ref, 100.0)
    assert r100['pairs'] == 9
    assert r100['trans_m']['rmse'] == pytest.approx(15.291364, **rel)
    assert r100['rot_deg']['mean'] == pytest.approx(2.234294, **rel)
    a10 = tr.rpe(est, ref, 10.0, all_pairs=True)
    assert a10['pairs'] == 2970 and a10['trans_m']['rmse'] == pytest.approx(1.699578, **rel)
    a100 = tr.rpe(est, ref, 100.0, all_pairs=True)
    assert a100['pairs'] == 2704 and a100['trans_m']['rmse'] == pytest.approx(15.347580, **rel)
