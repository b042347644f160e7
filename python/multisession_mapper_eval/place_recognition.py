"""Scan-level place recognition: precision-recall over the descriptor distance threshold.

For every queried scan of a session (place_recognition/<session>.csv):
- its top-1 match is a true positive when the ground-truth positions of the query scan and of
  the matched history scan are within `radius_m` (default 5 m);
- the query is a revisit (it has a true match) when some scan of an earlier session lies within
  `radius_m` of it in ground truth;
- at a threshold d the scans whose top-1 distance is <= d are predicted positive;
  precision(d) = true positives / predicted positives, recall(d) = true positives / revisits.
F1max = max over d of 2PR/(P+R). recall@1 = revisits whose top-1 is correct / revisits,
recall@5 = revisits with a correct match among the first 5 of `top_k` / revisits (no
threshold). Max recall at 100 % precision: the largest recall at a threshold where precision
is exactly 1 (0 when the closest match is already wrong). Figures are None without revisits.
"""

import numpy as np

from . import neighbors


def pr_curve(distances, correct, num_revisits):
    """(thresholds, precision, recall) for top-1 distances and their correctness flags."""
    distances = np.asarray(distances, dtype=np.float64)
    correct = np.asarray(correct, dtype=bool)
    if len(distances) == 0 or num_revisits == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    order = np.argsort(distances, kind='stable')
    distances, correct = distances[order], correct[order]
    true_pos = np.cumsum(correct)
    predicted = np.arange(1, len(distances) + 1)
    # Ties: a threshold admits all scans at that distance, so keep the last index of each run.
    last = np.append(distances[1:] != distances[:-1], True)
    thresholds = distances[last]
    precision = true_pos[last] / predicted[last]
    recall = true_pos[last] / float(num_revisits)
    return thresholds, precision, recall


def summarize_curve(precision, recall):
    if len(precision) == 0:
        return {'f1max': None, 'max_recall_at_full_precision': None}
    denom = precision + recall
    f1 = np.where(denom > 0, 2 * precision * recall / np.where(denom > 0, denom, 1), 0.0)
    full = recall[precision >= 1.0]
    return {'f1max': float(np.max(f1)),
            'max_recall_at_full_precision': float(np.max(full)) if len(full) else 0.0}


def evaluate_session(rows, session_truth, history_truths, radius_m=5.0, k=5,
                     stamp_tolerance_s=1e-3):
    """Figures of one session.

    rows: io.PlaceRecognitionRow list; session_truth: tr.Trajectory of the session (world);
    history_truths: dict session name -> tr.Trajectory (world) of the earlier sessions.
    """
    empty = {'f1max': None, 'recall_at_1': None, 'recall_at_5': None,
             'max_recall_at_full_precision': None, 'queries': 0, 'revisits': 0,
             'precision_at_threshold': None, 'recall_at_threshold': None,
             'curve': {'threshold': [], 'precision': [], 'recall': []}}
    if not rows or not history_truths:
        return empty
    history_positions = np.vstack([t.positions for t in history_truths.values()])

    def position(session, stamp):
        # Matches into a session that is not history (e.g. the session itself) are not
        # inter-session recognitions: no position, so they count as wrong.
        trajectory = session_truth if session is None else history_truths.get(session)
        if trajectory is None or stamp is None:
            return None
        pose = trajectory.lookup(stamp, stamp_tolerance_s)
        return None if pose is None else pose[:3, 3]

    distances, correct, queries, correct_k, matched = [], [], [], [], []
    for row in rows:
        query = position(None, row.stamp)
        if query is None or row.history_stamp is None or row.distance is None:
            continue
        top1 = position(row.history_session, row.history_stamp)
        is_correct = top1 is not None and np.linalg.norm(top1 - query) <= radius_m
        hits = []
        for session, stamp, _ in row.top_k[:k]:
            p = position(session, stamp)
            hits.append(p is not None and np.linalg.norm(p - query) <= radius_m)
        distances.append(row.distance)
        correct.append(is_correct)
        correct_k.append(is_correct or any(hits))
        matched.append(row.matched)
        queries.append(query)
    if not distances:
        return empty
    revisit = neighbors.has_neighbor_within(history_positions, np.array(queries), radius_m)
    correct, revisit = np.array(correct), np.array(revisit)
    correct_k, matched = np.array(correct_k), np.array(matched)
    num_revisits = int(revisit.sum())
    thresholds, precision, recall = pr_curve(distances, correct, num_revisits)
    result = dict(empty)
    result.update(summarize_curve(precision, recall))
    result['queries'] = len(distances)
    result['revisits'] = num_revisits
    if num_revisits:
        result['recall_at_1'] = float(np.sum(correct & revisit) / num_revisits)
        result['recall_at_5'] = float(np.sum(correct_k & revisit) / num_revisits)
        result['recall_at_threshold'] = float(np.sum(correct & matched) / num_revisits)
    if matched.any():
        result['precision_at_threshold'] = float(np.sum(correct & matched) / matched.sum())
    result['curve'] = {'threshold': thresholds.tolist(), 'precision': precision.tolist(),
                       'recall': recall.tolist()}
    return result
