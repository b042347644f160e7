"""Map size figures: points per session and in total, bytes on disk, growth per session.

Points are those of active submaps (status `active`), read from the PCD headers (the manifest's
`points` field is used when a file is missing). Bytes on disk: every file under the map
directory. Per session: the files that belong to it (submaps/<session>/, trajectories/<session>*,
loops/<session>.csv, place_recognition/<session>.csv, dynamics/<session>_*, timing/<session>.yaml);
shared files (manifest, graph, database, changelog) are counted in `bytes_shared`.
"""

import os

from . import io
from . import pcd


def _session_files(map_path, session):
    files = []
    submap_dir = os.path.join(map_path, 'submaps', session)
    if os.path.isdir(submap_dir):
        files += [os.path.join(submap_dir, f) for f in os.listdir(submap_dir)]
    for folder, prefix in (('trajectories', session + '.'), ('trajectories', session + '_'),
                           ('loops', session + '.'), ('place_recognition', session + '.'),
                           ('dynamics', session + '_'), ('timing', session + '.')):
        path = os.path.join(map_path, folder)
        if os.path.isdir(path):
            files += [os.path.join(path, f) for f in os.listdir(path) if f.startswith(prefix)]
    return sorted(set(f for f in files if os.path.isfile(f)))


def submap_points(submap):
    if os.path.isfile(submap.file):
        try:
            return pcd.read_pcd_header(submap.file).points
        except pcd.PcdError:
            pass
    return submap.points


def compute(map_dir):
    points_per_session = []
    bytes_per_session = []
    submaps_per_session = []
    attributed = 0
    for name in map_dir.session_names:
        active = [s for s in map_dir.submaps_of(name) if s.status == 'active']
        points_per_session.append(int(sum(submap_points(s) for s in active)))
        submaps_per_session.append(len(active))
        size = sum(os.path.getsize(f) for f in _session_files(map_dir.path, name))
        bytes_per_session.append(int(size))
        attributed += size
    total_bytes = io.directory_bytes(map_dir.path)
    return {'points_total': int(sum(points_per_session)),
            'points_per_session': points_per_session,
            'active_submaps_per_session': submaps_per_session,
            'submaps_total': len(map_dir.submaps),
            'submaps_active': int(sum(submaps_per_session)),
            'bytes_on_disk': int(total_bytes),
            'bytes_on_disk_per_session': bytes_per_session,
            'bytes_shared': int(total_bytes - attributed)}
