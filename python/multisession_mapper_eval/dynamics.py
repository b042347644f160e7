"""Dynamic point removal with the DynamicMap benchmark's definitions (Zhang et al., ITSC 2023).

Ground truth: the union of the labelled truth clouds of the map's sessions (world frame),
de-duplicated per (voxel of `label_voxel_m`, object id), expressed in the map frame by the
fixed transform T_map_world (no fitted alignment). Each point is
- high-dynamic: class 9 (moving car) or 10 (pedestrian);
- low-dynamic: a point of an object that is absent from at least one of the map's sessions
  that saw its place: by default when that session's own returns fall inside the object's
  grown box (low_dynamic_by_footprint), or when its truth trajectory passes within
  `observe_radius_m` of the object (low_dynamic_objects, the 'radius' rule);
- static: everything else; canopy (class 6) static points are also reported on their own.
Only points within `eval_range_m` of a truth scan position of the map's sessions are evaluated
(the pipeline maps returns up to its own range limit; farther ones would measure range, not
dynamic removal). A point is kept when the final map (all active submaps, transformed by their
origins) has a point within `kept_radius_m` of the point's own category, each map point taking
the category of its nearest ground-truth point (label transfer; see kept_points).
SA = static kept / static, DA = dynamic removed / dynamic, AA = sqrt(SA DA),
HA = 2 SA DA / (SA + DA). Undefined ratios (empty sets) are None.
"""

import collections

import numpy as np

from . import neighbors
from . import trajectory as tr

GroundTruth = collections.namedtuple('GroundTruth', [
    'points',           # (N, 3) map frame: de-duplicated and within the evaluation range
    'labels',           # (N,) class
    'object_ids',       # (N,)
    'category',         # (N,) STATIC / LOW / HIGH
    'excluded',         # points left out by the evaluation range
    'all_points',       # (M, 3) map frame: every labelled point (for the label transfer)
    'all_category',     # (M,)
    'path_distance',    # (N,) distance [m] to the nearest truth scan position (inf: none)
    'low_presence'])    # low-dynamic object id -> tuple of the map sessions it is present in

# Bands of the distance to the path [m] of the breakdown (the last one is open).
RANGE_BANDS_M = (0.0, 10.0, 20.0, 30.0, 40.0)

HIGH_DYNAMIC_CLASSES = (9, 10)
CANOPY_CLASS = 6
# The simulator's point classes (docs/simulator.md, labels PCD).
CLASS_NAMES = ('terrain', 'building', 'wall', 'pole', 'hedge', 'trunk', 'canopy', 'parked car',
               'movable', 'moving car', 'pedestrian')
STATIC, LOW, HIGH = 0, 1, 2


def _changing_objects(objects, session_names):
    """(object, set of sessions it is present in) for static objects absent from a session."""
    for obj in objects:
        if (str(obj.get('class', '')) in ('moving_car', 'pedestrian') or obj.get('trajectory')
                or 'sessions' not in obj):
            continue
        present = {str(s) for s in obj.get('sessions') or []}
        if not all(s in present for s in session_names):
            yield obj, present


def footprint_points(points_sorted_x, obj, margin_m):
    """Number of points (sorted by x) inside the object's box grown by `margin_m`.

    The box is the object's pose (x, y, z centre, yaw) and size from world.yaml.
    """
    pose = list(obj.get('pose') or [0.0, 0.0, 0.0, 0.0]) + [0.0] * 4
    size = np.asarray(list(obj.get('size') or [0.0, 0.0, 0.0]) + [0.0] * 3, dtype=float)[:3]
    half = size / 2.0 + margin_m
    reach = float(np.hypot(half[0], half[1]))
    xs = points_sorted_x[:, 0]
    lo, hi = np.searchsorted(xs, pose[0] - reach), np.searchsorted(xs, pose[0] + reach)
    local = points_sorted_x[lo:hi] - np.array(pose[:3], dtype=float)
    c, s = np.cos(pose[3]), np.sin(pose[3])
    u = c * local[:, 0] + s * local[:, 1]
    v = -s * local[:, 0] + c * local[:, 1]
    inside = (np.abs(u) <= half[0]) & (np.abs(v) <= half[1]) & (np.abs(local[:, 2]) <= half[2])
    return int(np.sum(inside))


def _min_distance_xy(trajectory, xy):
    if trajectory is None or len(trajectory) == 0:
        return np.inf
    return float(np.min(np.linalg.norm(trajectory.positions[:, :2] - xy, axis=1)))


def low_dynamic_by_footprint(objects, session_names, session_points, margin_m=0.3,
                             min_points=5, truth_trajectories=None, max_range_m=0.0):
    """Ids of objects absent from some session that saw their place (visibility rule).

    A session saw the place of an object it does not contain when its labelled returns hold at
    least `min_points` points inside the object's box grown by `margin_m` (the ground under a
    vanished car, or another car parked in the same slot) and, when max_range_m > 0, its truth
    trajectory came within max_range_m (horizontal) of the object, so that the pipeline's
    range limit allowed it to see the place too. session_points: session name -> (N, 3)
    world-frame label points of that session; truth_trajectories: name -> tr.Trajectory.
    """
    sorted_points = {}
    result = set()
    for obj, present in _changing_objects(objects, session_names):
        for name in session_names:
            if name in present or name not in session_points:
                continue
            if max_range_m and max_range_m > 0 and truth_trajectories is not None:
                xy = np.array((obj.get('pose') or [0.0, 0.0])[:2], dtype=float)
                if _min_distance_xy(truth_trajectories.get(name), xy) > max_range_m:
                    continue
            if name not in sorted_points:
                pts = np.asarray(session_points[name], dtype=np.float64)
                sorted_points[name] = pts[np.argsort(pts[:, 0], kind='stable')]
            if footprint_points(sorted_points[name], obj, margin_m) >= min_points:
                result.add(int(obj['id']))
                break
    return result


def low_dynamic_objects(objects, session_names, truth_trajectories, observe_radius_m):
    """Ids of objects absent from some session (of `session_names`) that observed their place.

    Radius rule: a session observed the place when its truth trajectory passes within
    `observe_radius_m` (horizontal) of the object's centre. objects: world.yaml object dicts;
    truth_trajectories: session name -> tr.Trajectory.
    """
    result = set()
    for obj, present in _changing_objects(objects, session_names):
        pose = obj.get('pose') or [0.0, 0.0, 0.0]
        centre = np.array(pose[:2], dtype=np.float64)
        for name in session_names:
            trajectory = truth_trajectories.get(name)
            if trajectory is None or name in present or len(trajectory) == 0:
                continue
            if np.min(np.linalg.norm(trajectory.positions[:, :2] - centre, axis=1)) \
                    <= observe_radius_m:
                result.add(int(obj['id']))
                break
    return result


def classify(labels, object_ids, low_objects):
    """Per-point category (STATIC, LOW, HIGH)."""
    category = np.full(len(labels), STATIC, dtype=np.int8)
    if low_objects:
        category[np.isin(object_ids, np.array(sorted(low_objects), dtype=np.int64))] = LOW
    category[np.isin(labels, HIGH_DYNAMIC_CLASSES)] = HIGH
    return category


def deduplicate(points, object_ids, voxel_m):
    """Indices of one point per (voxel, object id)."""
    if len(points) == 0 or voxel_m <= 0:
        return np.arange(len(points))
    cells = np.floor(points / voxel_m).astype(np.int64)
    cells -= cells.min(axis=0)
    ids = object_ids.astype(np.int64)
    ids -= ids.min()
    dims = np.append(cells.max(axis=0), ids.max()) + 1
    if np.prod(dims.astype(np.float64)) < 2.0 ** 62:  # one int64 key: fast and small
        key = ((cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]) * dims[3] + ids
        _, first = np.unique(key, return_index=True)
    else:
        _, first = np.unique(np.column_stack([cells, ids]), axis=0, return_index=True)
    return np.sort(first)


def _ratio(num, den):
    return float(num) / float(den) if den else None


def scores(sa, da):
    """The DynamicMap figures from SA and DA (None when either is undefined)."""
    out = {'sa': sa, 'da': da, 'aa': None, 'ha': None}
    if sa is not None and da is not None:
        out['aa'] = float(np.sqrt(sa * da))
        out['ha'] = float(2 * sa * da / (sa + da)) if sa + da > 0 else 0.0
    return out


def kept_points(gt_points_map, category, map_points, kept_radius_m, rule='same_category',
                transfer_points=None, transfer_category=None):
    """Boolean per ground-truth point: does the final map keep it?

    rule 'any': some map point lies within the radius. rule 'same_category' (default): each
    map point takes the category of its nearest ground-truth point within the radius (label
    transfer, so a resampled map is judged like DynamicMap judges a labelled subset of the
    input); a ground-truth point is kept when a map point of its own category lies within the
    radius. Without it a perfectly cleaned map would still "keep" the lowest points of a car
    or a pedestrian through the road surface right below them. The labels are transferred
    from `transfer_points` (default: the evaluated points; better: every labelled point
    before de-duplication, so that no map point borrows a neighbouring object's label).
    """
    if transfer_points is None:
        transfer_points, transfer_category = gt_points_map, category
    if rule == 'any':
        return neighbors.has_neighbor_within(map_points, gt_points_map, kept_radius_m)
    if rule != 'same_category':
        raise ValueError('unknown kept rule %s' % rule)
    nearest = neighbors.nearest_within(transfer_points, map_points, kept_radius_m)
    map_category = np.where(nearest >= 0, transfer_category[np.maximum(nearest, 0)], -1)
    kept = np.zeros(len(gt_points_map), dtype=bool)
    for value in (STATIC, LOW, HIGH):
        mine = category == value
        if mine.any():
            kept[mine] = neighbors.has_neighbor_within(map_points[map_category == value],
                                                       gt_points_map[mine], kept_radius_m)
    return kept


def evaluate(gt_points_map, labels, category, map_points, kept_radius_m, rule='same_category',
             transfer_points=None, transfer_category=None):
    """The dynamics section of report.json from GT points (map frame) and the final map."""
    map_points = np.asarray(map_points, dtype=np.float64).reshape(-1, 3)
    kept = kept_points(gt_points_map, category, map_points, kept_radius_m, rule,
                       transfer_points, transfer_category)
    static = category == STATIC
    low = category == LOW
    high = category == HIGH
    canopy = static & (labels == CANOPY_CLASS)
    sa = _ratio(np.sum(kept & static), np.sum(static))
    da_low = _ratio(np.sum(~kept & low), np.sum(low))
    da_high = _ratio(np.sum(~kept & high), np.sum(high))
    da_all = _ratio(np.sum(~kept & (low | high)), np.sum(low | high))
    return {
        'low': scores(sa, da_low),
        'high': scores(sa, da_high),
        'all_dynamic': scores(sa, da_all),
        'static': {'sa': sa},
        'canopy': {'sa': _ratio(np.sum(kept & canopy), np.sum(canopy))},
        'kept_radius_m': float(kept_radius_m),
        'kept_rule': rule,
        'points': {'static': int(np.sum(static)), 'low': int(np.sum(low)),
                   'high': int(np.sum(high)), 'canopy': int(np.sum(canopy)),
                   'map': int(len(map_points)),
                   'static_kept': int(np.sum(kept & static)),
                   'low_removed': int(np.sum(~kept & low)),
                   'high_removed': int(np.sum(~kept & high))},
    }, kept


def ground_truth(truth, map_session_names, truth_names, truth_trajectories, t_map_world,
                 observe_radius_m, label_voxel_m, eval_range_m=0.0, observed_rule='footprint',
                 footprint_margin_m=0.3, footprint_min_points=5):
    """The GroundTruth (map frame) of the union of the sessions' truth clouds.

    observed_rule decides which sessions saw the place of a changing object: 'footprint'
    (default; label points of the session inside the object's grown box, the session's
    trajectory within eval_range_m; see low_dynamic_by_footprint) or 'radius' (trajectory
    within observe_radius_m).

    truth_names: map session name -> truth session name; truth_trajectories: map session
    name -> tr.Trajectory (world frame). eval_range_m > 0 keeps only points within that
    distance of a truth scan position of the map's sessions and, when the truth clouds carry
    the simulator's `range` field, only points measured from at most that range at least once
    (the pipeline does not map farther returns); `excluded` counts the others. Returns None
    when no labelled cloud exists.
    """
    clouds = []
    session_points = {}
    excluded = 0
    for name in map_session_names:
        loaded = truth.labels(truth_names[name]) if truth_names.get(name) else None
        if loaded is not None:
            session_points[name] = loaded[0]
            points, labels, ids = loaded[:3]
            ranges = loaded[3] if len(loaded) > 3 else None
            if eval_range_m and eval_range_m > 0 and ranges is not None:
                # Returns measured only from farther than the pipeline's range limit could
                # never be mapped (0: unknown range, kept).
                seen = (ranges <= 0) | (ranges <= eval_range_m)
                excluded += int(np.sum(~seen))
                points, labels, ids = points[seen], labels[seen], ids[seen]
            clouds.append((points, labels, ids, loaded[:3]))
    if not clouds:
        return None
    points = np.vstack([c[0] for c in clouds])
    labels = np.concatenate([c[1] for c in clouds])
    object_ids = np.concatenate([c[2] for c in clouds])
    # Labels are transferred from every labelled point, also those beyond the range limit.
    all_points = np.vstack([c[3][0] for c in clouds])
    all_labels = np.concatenate([c[3][1] for c in clouds])
    all_ids = np.concatenate([c[3][2] for c in clouds])
    keep = deduplicate(points, object_ids, label_voxel_m)
    points, labels, object_ids = points[keep], labels[keep], object_ids[keep]
    positions = [truth_trajectories[n].positions for n in map_session_names
                 if n in truth_trajectories and len(truth_trajectories[n]) > 0]
    path_distance = (neighbors.min_distances(np.vstack(positions), points) if positions
                     else np.full(len(points), np.inf))
    if eval_range_m and eval_range_m > 0 and positions:
        inside = path_distance <= eval_range_m
        excluded += int(np.sum(~inside))
        points, labels, object_ids = points[inside], labels[inside], object_ids[inside]
        path_distance = path_distance[inside]
    # world.yaml names sessions by the simulator's names: translate to map names.
    to_map = {truth_names[m]: m for m in map_session_names if truth_names.get(m)}
    objects = []
    for obj in truth.objects:
        obj = dict(obj)
        if 'sessions' in obj:
            obj['sessions'] = [to_map.get(str(s), str(s)) for s in obj['sessions']]
        objects.append(obj)
    if observed_rule == 'footprint':
        low = low_dynamic_by_footprint(objects, map_session_names, session_points,
                                       footprint_margin_m, footprint_min_points,
                                       truth_trajectories, eval_range_m)
    elif observed_rule == 'radius':
        low = low_dynamic_objects(objects, map_session_names, truth_trajectories,
                                  observe_radius_m)
    else:
        raise ValueError('unknown observed rule %s' % observed_rule)
    category = classify(labels, object_ids, low)
    presence = {int(obj['id']): tuple(s for s in map_session_names if s in present)
                for obj, present in _changing_objects(objects, map_session_names)
                if int(obj['id']) in low}
    return GroundTruth(tr.transform_points(t_map_world, points), labels, object_ids, category,
                       excluded, tr.transform_points(t_map_world, all_points),
                       classify(all_labels, all_ids, low), path_distance, presence)


def breakdown(category, kept, path_distance, object_ids, low_presence, bands=RANGE_BANDS_M,
              labels=None):
    """Where the dynamic-removal figures come from (a diagnosis, next to the totals).

    'by_range': per band of the distance to the path (band i is [bands[i], bands[i+1]), the last
    one open), SA and the DA of the low- and high-dynamic points with their counts; points with
    no finite distance (no truth trajectory) are in no band, and with none at all the list is
    empty.
    'low_by_presence': per set of map sessions a low-dynamic object is present in, the DA of its
    points (e.g. ('s00',): in the first session only, gone later). Undefined ratios are None.
    'by_class' (with `labels`): per simulator class, in class order, the static points (parked
    cars and movable objects present in every session that saw their place are static too),
    the low- and high-dynamic points, how many of each were kept (static) or removed (dynamic),
    SA and both DAs: which classes the lost static and the kept dynamic points belong to.
    """
    static, low, high = category == STATIC, category == LOW, category == HIGH
    finite = np.isfinite(path_distance)
    by_range = []
    for i, lo in enumerate(bands if finite.any() else ()):
        hi = bands[i + 1] if i + 1 < len(bands) else None
        band = finite & (path_distance >= lo) & (path_distance < hi if hi is not None else True)
        by_range.append({
            'from_m': float(lo), 'to_m': None if hi is None else float(hi),
            'sa': _ratio(np.sum(kept & static & band), np.sum(static & band)),
            'low_da': _ratio(np.sum(~kept & low & band), np.sum(low & band)),
            'high_da': _ratio(np.sum(~kept & high & band), np.sum(high & band)),
            'static_points': int(np.sum(static & band)), 'low_points': int(np.sum(low & band)),
            'high_points': int(np.sum(high & band))})
    groups = collections.defaultdict(list)
    for object_id, sessions in (low_presence or {}).items():
        groups[tuple(sessions)].append(object_id)
    by_presence = []
    for sessions in sorted(groups, key=lambda k: (len(k), k)):
        mine = low & np.isin(object_ids, np.array(sorted(groups[sessions]), dtype=np.int64))
        if not mine.any():
            continue
        by_presence.append({'present_in': list(sessions), 'objects': len(groups[sessions]),
                            'points': int(np.sum(mine)),
                            'da': _ratio(np.sum(~kept & mine), np.sum(mine))})
    by_class = []
    if labels is not None:
        for value in np.unique(labels):
            mine = labels == value
            name = CLASS_NAMES[value] if 0 <= value < len(CLASS_NAMES) else 'class %d' % value
            s, lo, hi = mine & static, mine & low, mine & high
            by_class.append({
                'class': int(value), 'name': name,
                'static_points': int(np.sum(s)), 'static_kept': int(np.sum(kept & s)),
                'low_points': int(np.sum(lo)), 'low_removed': int(np.sum(~kept & lo)),
                'high_points': int(np.sum(hi)), 'high_removed': int(np.sum(~kept & hi)),
                'sa': _ratio(np.sum(kept & s), np.sum(s)),
                'low_da': _ratio(np.sum(~kept & lo), np.sum(lo)),
                'high_da': _ratio(np.sum(~kept & hi), np.sum(hi))})
    return {'by_range': by_range, 'low_by_presence': by_presence, 'by_class': by_class}
