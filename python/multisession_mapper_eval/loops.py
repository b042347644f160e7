"""The reference paper's inter-session loop-closure table and intra-session loop figures.

Per new session (every session after the first, in merge order), each of its submaps is:
- correct: it has at least one accepted `inter` or `inter_sequence` loop (the loops of place
  recognition: by descriptor votes, or placed by a neighbour's loop when the votes found
  nothing) and every such loop of it is
  correct, i.e. the estimated T_history_current is within `max_trans_m` and `max_rot_deg` of
  the ground-truth relative pose of the two submap origins AND the two submaps overlap in
  ground truth (some scan positions of the two within `overlap_radius_m`);
- wrong: it has an accepted `inter` loop that is not correct;
- undefined: no accepted `inter` or `inter_sequence` loop; split into
  - new (really new place): fewer than `overlap_min_fraction` of its scans have a scan of an
    earlier session (ground-truth position) within `overlap_radius_m`;
  - missed: otherwise (overlap existed but no match was accepted).
The origin of a submap is the sensor pose at its `first_stamp`, looked up in the truth TUM (times
the inverse of that scan's pose in the submap: the identity but for a re-anchored first submap).
Intra-session loops (kind `intra`): accepted, correct, wrong by the same pose test, without the
overlap condition (an exact edge between submaps whose paths stay apart is still right).
A submap that cannot be judged (missing from the manifest, whose `fused` entries must stay, or
stamps missing from the truth) is `unknown` and counted in `submaps_unknown`, never guessed.
Loops found by the proximity search after alignment (kind `inter_proximity`) are counted
separately and do not change the table (the paper's table measures place recognition).
Submaps correct only through `inter_sequence` loops are counted in `submaps_correct_by_sequence`
as well, so the descriptor-only figure stays visible.
"""

import numpy as np

from . import neighbors
from . import trajectory as tr


class LoopOptions(object):
    def __init__(self, max_trans_m=0.3, max_rot_deg=1.0, overlap_radius_m=10.0,
                 overlap_min_fraction=0.5, stamp_tolerance_s=1e-3):
        self.max_trans_m = max_trans_m
        self.max_rot_deg = max_rot_deg
        self.overlap_radius_m = overlap_radius_m
        self.overlap_min_fraction = overlap_min_fraction
        self.stamp_tolerance_s = stamp_tolerance_s


class TruthLookup(object):
    """Ground-truth poses of submap origins and scan positions (world frame)."""

    def __init__(self, truth_trajectories, tolerance_s):
        self.trajectories = truth_trajectories  # map session name -> tr.Trajectory
        self.tolerance_s = tolerance_s

    def pose(self, session, stamp):
        trajectory = self.trajectories.get(session)
        return None if trajectory is None else trajectory.lookup(stamp, self.tolerance_s)

    def origin(self, submap):
        """Truth pose (world frame) of the submap's origin: the pose at its first stamp, times
        the inverse of that scan's pose in the submap (the identity but for a re-anchored first
        submap)."""
        pose = self.pose(submap.session, submap.first_stamp)
        return None if pose is None else pose @ tr.inverse(submap.first_scan_pose)

    def scan_positions(self, submap):
        trajectory = self.trajectories.get(submap.session)
        if trajectory is None:
            return np.zeros((0, 3))
        if len(submap.scan_stamps):
            poses = [trajectory.lookup(s, self.tolerance_s) for s in submap.scan_stamps]
            return np.array([p[:3, 3] for p in poses if p is not None]).reshape(-1, 3)
        inside = ((trajectory.stamps >= submap.first_stamp - self.tolerance_s)
                  & (trajectory.stamps <= submap.last_stamp + self.tolerance_s))
        return trajectory.positions[inside]


def _judge(loop, submaps_by_key, lookup, options, require_overlap=True):
    """(correct, trans_err_m, rot_err_deg) of one loop row.

    correct is None when the row cannot be judged (a submap missing from the manifest or a
    stamp missing from the truth); an accepted row without a pose is wrong. With
    `require_overlap` (place recognition: a correct match is a real revisit) the two submaps'
    truth scan positions must also come within `overlap_radius_m`; without it (intra-session
    loops, whose question is whether the graph edge is right) the pose alone decides: two
    submaps whose paths stay 10 m apart can still share a street and register exactly.
    """
    current = submaps_by_key.get((loop.current_session, loop.current_submap))
    history = submaps_by_key.get((loop.history_session, loop.history_submap))
    if current is None or history is None:
        return None, None, None
    t_c = lookup.origin(current)
    t_h = lookup.origin(history)
    if t_c is None or t_h is None:
        return None, None, None
    if loop.pose is None:
        return False, None, None
    truth = tr.inverse(t_h) @ t_c
    trans_err, rot_err = tr.relative_error(loop.pose, truth)
    pos_c, pos_h = lookup.scan_positions(current), lookup.scan_positions(history)
    overlap = not require_overlap or bool(
        len(pos_c) and len(pos_h)
        and neighbors.has_neighbor_within(pos_h, pos_c, options.overlap_radius_m).any())
    ok = overlap and trans_err <= options.max_trans_m and rot_err <= options.max_rot_deg
    return ok, trans_err, rot_err


def _median(values):
    return float(np.median(values)) if len(values) else None


def session_table(map_dir, session_index, truth_trajectories, options):
    """The loop figures of one session (a dict with the report.json keys)."""
    name = map_dir.session_names[session_index]
    history_names = map_dir.session_names[:session_index]
    lookup = TruthLookup(truth_trajectories, options.stamp_tolerance_s)
    submaps_by_key = {s.key: s for s in map_dir.submaps}
    rows = map_dir.loops(name)
    ids = sorted({s.id for s in map_dir.submaps_of(name)}
                 | {r.current_submap for r in rows if r.current_session in ('', name)})
    result = {'submaps_total': len(ids), 'submaps_correct': 0, 'submaps_wrong': 0,
              'submaps_correct_by_sequence': 0,
              'sequence_loops_accepted': 0, 'sequence_loops_correct': 0,
              'sequence_loops_wrong': 0,
              'submaps_undefined_new': 0, 'submaps_undefined_missed': 0,
              'submaps_with_truth_overlap': 0,
              'inter_loops_accepted': 0, 'inter_loops_correct': 0, 'inter_loops_wrong': 0,
              'inter_loop_trans_err_median_m': None, 'inter_loop_rot_err_median_deg': None,
              'proximity_loops_accepted': 0, 'proximity_loops_correct': 0,
              'proximity_loops_wrong': 0,
              'intra_loops_accepted': 0, 'intra_loops_correct': 0, 'intra_loops_wrong': 0,
              'intra_loop_trans_err_median_m': None, 'intra_loop_rot_err_median_deg': None,
              'submaps_unknown': 0, 'loops_unjudged': 0, 'submap_status': {}}
    # Intra-session loops exist for every session, including the first.
    intra_t, intra_r = [], []
    for row in rows:
        if row.kind == 'intra' and row.status == 'accepted':
            ok, t_err, r_err = _judge(row, submaps_by_key, lookup, options,
                                      require_overlap=False)
            result['intra_loops_accepted'] += 1
            if ok is None:
                result['loops_unjudged'] += 1
            else:
                result['intra_loops_correct' if ok else 'intra_loops_wrong'] += 1
            if t_err is not None:
                intra_t.append(t_err)
                intra_r.append(r_err)
    result['intra_loop_trans_err_median_m'] = _median(intra_t)
    result['intra_loop_rot_err_median_deg'] = _median(intra_r)
    if not history_names:
        return result  # no history: the inter-session counts stay 0

    history_positions = [lookup.trajectories[h].positions for h in history_names
                         if h in lookup.trajectories]
    history_positions = np.vstack(history_positions) if history_positions else np.zeros((0, 3))
    accepted = {}
    by_descriptor = {}  # submap id -> whether one of its accepted loops is of kind `inter`
    inter_t, inter_r = [], []
    for row in rows:
        if row.status != 'accepted' or row.kind not in ('inter', 'inter_sequence',
                                                        'inter_proximity'):
            continue
        ok, t_err, r_err = _judge(row, submaps_by_key, lookup, options)
        if ok is None:
            result['loops_unjudged'] += 1
        if row.kind in ('inter', 'inter_sequence'):
            accepted.setdefault(row.current_submap, []).append(ok)
            by_descriptor.setdefault(row.current_submap, False)
            if row.kind == 'inter':
                by_descriptor[row.current_submap] = True
            prefix = 'inter_loops_' if row.kind == 'inter' else 'sequence_loops_'
            result[prefix + 'accepted'] += 1
            if ok is not None:
                result[prefix + ('correct' if ok else 'wrong')] += 1
            if t_err is not None:
                inter_t.append(t_err)
                inter_r.append(r_err)
        else:
            result['proximity_loops_accepted'] += 1
            if ok is not None:
                result['proximity_loops_correct' if ok else 'proximity_loops_wrong'] += 1
    result['inter_loop_trans_err_median_m'] = _median(inter_t)
    result['inter_loop_rot_err_median_deg'] = _median(inter_r)

    for submap_id in ids:
        submap = submaps_by_key.get((name, submap_id))
        positions = lookup.scan_positions(submap) if submap is not None else np.zeros((0, 3))
        near = neighbors.has_neighbor_within(history_positions, positions,
                                             options.overlap_radius_m)
        overlaps = bool(len(positions)) and near.mean() >= options.overlap_min_fraction
        result['submaps_with_truth_overlap'] += int(overlaps)
        verdicts = accepted.get(submap_id)
        if verdicts and False in verdicts:
            status = 'wrong'
        elif verdicts and None not in verdicts:
            status = 'correct'
        elif verdicts or submap is None:
            status = 'unknown'  # cannot be judged: missing from the manifest or the truth
        else:
            status = 'undefined_missed' if overlaps else 'undefined_new'
        result['submaps_' + status] += 1
        if status == 'correct' and not by_descriptor.get(submap_id, True):
            result['submaps_correct_by_sequence'] += 1
        result['submap_status'][str(submap_id)] = status
    return result
