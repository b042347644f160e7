"""Radius queries between point sets: scipy's cKDTree when available, else a numpy voxel hash.

Debian's python3-scipy provides cKDTree; the numpy fallback gives identical answers (it checks
the 27 cells around each query with a cell size equal to the radius), only slower.
"""

import numpy as np

try:  # pragma: no cover - depends on the machine
    from scipy.spatial import cKDTree
except ImportError:  # pragma: no cover
    cKDTree = None

_OFFSETS = np.array([[a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)])


def _as_points(points):
    return np.asarray(points, dtype=np.float64).reshape(-1, 3)


def _voxel_pairs(reference, query, radius, chunk=200000):
    """Yields (query_index, reference_index, squared distance) of candidate pairs.

    Every pair closer than `radius` is among the candidates (cell size = radius, 27 cells).
    """
    origin = np.minimum(reference.min(axis=0), query.min(axis=0)) - 2 * radius
    ref_cells = np.floor((reference - origin) / radius).astype(np.int64)
    dims = np.max(np.vstack([ref_cells.max(axis=0),
                             np.floor((query - origin) / radius).max(axis=0)]), axis=0) + 3
    ref_keys = (ref_cells[:, 0] * dims[1] + ref_cells[:, 1]) * dims[2] + ref_cells[:, 2]
    order = np.argsort(ref_keys, kind='stable')
    ref_keys = ref_keys[order]
    for start in range(0, len(query), chunk):
        q = query[start:start + chunk]
        q_cells = np.floor((q - origin) / radius).astype(np.int64)
        for off in _OFFSETS:
            cells = q_cells + off
            keys = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
            lo = np.searchsorted(ref_keys, keys, 'left')
            counts = np.searchsorted(ref_keys, keys, 'right') - lo
            total = int(counts.sum())
            if total == 0:
                continue
            q_index = np.repeat(np.arange(len(q)), counts)
            r_sorted = np.repeat(lo - np.cumsum(counts) + counts, counts) + np.arange(total)
            r_index = order[r_sorted]
            d2 = np.sum((q[q_index] - reference[r_index]) ** 2, axis=1)
            yield q_index + start, r_index, d2


def has_neighbor_within(reference, query, radius, use_scipy=True):
    """Boolean (len(query),): True where `reference` has a point within `radius` [m]."""
    reference, query = _as_points(reference), _as_points(query)
    if len(reference) == 0 or len(query) == 0:
        return np.zeros(len(query), dtype=bool)
    if use_scipy and cKDTree is not None:
        distances, _ = cKDTree(reference).query(query, k=1, distance_upper_bound=radius * 1.0001,
                                                workers=-1)
        return distances <= radius
    found = np.zeros(len(query), dtype=bool)
    for q_index, _, d2 in _voxel_pairs(reference, query, radius):
        found[q_index[d2 <= radius * radius]] = True
    return found


def nearest_within(reference, query, radius, use_scipy=True):
    """Index of the nearest reference point within `radius` for each query point, else -1."""
    reference, query = _as_points(reference), _as_points(query)
    index = np.full(len(query), -1, dtype=np.int64)
    if len(reference) == 0 or len(query) == 0:
        return index
    if use_scipy and cKDTree is not None:
        distances, found = cKDTree(reference).query(query, k=1, workers=-1,
                                                    distance_upper_bound=radius * 1.0001)
        ok = distances <= radius
        index[ok] = found[ok]
        return index
    best = np.full(len(query), np.inf)
    for q_index, r_index, d2 in _voxel_pairs(reference, query, radius):
        inside = d2 <= radius * radius
        q_index, r_index, d2 = q_index[inside], r_index[inside], d2[inside]
        if len(q_index) == 0:
            continue
        # Per query keep the smallest distance of this batch (ties: lowest reference index).
        order = np.lexsort((r_index, d2, q_index))
        q_index, r_index, d2 = q_index[order], r_index[order], d2[order]
        first = np.append(True, q_index[1:] != q_index[:-1])
        q_index, r_index, d2 = q_index[first], r_index[first], d2[first]
        better = d2 < best[q_index]
        best[q_index[better]] = d2[better]
        index[q_index[better]] = r_index[better]
    return index


def min_distances(reference, query):
    """Distance from each query point to its nearest reference point (inf if none)."""
    reference, query = _as_points(reference), _as_points(query)
    if len(reference) == 0:
        return np.full(len(query), np.inf)
    if cKDTree is not None:
        return cKDTree(reference).query(query, k=1, workers=-1)[0]
    out = np.empty(len(query))
    for start in range(0, len(query), 2048):
        q = query[start:start + 2048]
        best = np.full(len(q), np.inf)
        for rs in range(0, len(reference), 8192):
            d = np.linalg.norm(q[:, None, :] - reference[None, rs:rs + 8192, :], axis=2)
            best = np.minimum(best, d.min(axis=1))
        out[start:start + 2048] = best
    return out
