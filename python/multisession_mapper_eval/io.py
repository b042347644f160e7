"""Readers for the map directory (docs/map_format.md) and the simulator output (docs/simulator.md).

Everything optional in the map directory (loops, place recognition, dynamics, timing) may be
absent: the readers return empty containers and the evaluator reports null figures and a
warning, so that a partial pipeline can still be measured.
"""

import csv
import os

import numpy as np
import yaml

from . import pcd
from . import trajectory as tr


class EvalInputError(RuntimeError):
    """A missing or malformed input file; the message names it."""


def _indent(line):
    return len(line) - len(line.lstrip(' '))


def _drop_blocks(text, keys):
    """Replaces every block-style `key:` mapping entry named in `keys` by `key: omitted`.

    The blocks are the lines indented deeper than the key (or list items at the key's level
    that follow it). Used to skip the parts of world.yaml no metric needs (terrain grid, object
    parts, moving-object trajectories), which make up most of its parsing time.
    """
    out, skip_indent = [], None
    for line in text.splitlines(True):
        stripped = line.strip()
        if skip_indent is not None:
            if not stripped or _indent(line) > skip_indent or (
                    _indent(line) == skip_indent and stripped.startswith('- ')):
                continue
            skip_indent = None
        key, sep, rest = stripped.partition(':')
        if sep and key in keys and not rest.strip() and not stripped.startswith('- '):
            skip_indent = _indent(line)
            out.append(' ' * skip_indent + key + ': omitted\n')
            continue
        out.append(line)
    return ''.join(out)


def _load_yaml(path, omit_blocks=()):
    """Parses a YAML file; block entries named in `omit_blocks` are read as 'omitted'."""
    if not os.path.isfile(path):
        raise EvalInputError('missing file: %s' % path)
    try:
        with open(path) as f:
            text = f.read()
        if omit_blocks:
            text = _drop_blocks(text, omit_blocks)
        # libyaml's loader when available: world.yaml can be megabytes.
        return yaml.load(text, Loader=getattr(yaml, 'CSafeLoader', yaml.SafeLoader)) or {}
    except yaml.YAMLError as error:
        raise EvalInputError('malformed YAML in %s: %s' % (path, error)) from None


def _read_csv(path):
    if not os.path.isfile(path):
        return []
    with open(path, newline='') as f:
        return [{k.strip(): (v.strip() if isinstance(v, str) else v) for k, v in row.items()
                 if k is not None} for row in csv.DictReader(f)]


def _float(value, default=None):
    try:
        return float(value) if value not in (None, '') else default
    except ValueError:
        return default


class Submap(object):
    def __init__(self, entry, map_dir):
        self.session = str(entry['session'])
        self.id = int(entry['id'])
        self.origin = tr.pose_from_list(entry['origin'])
        self.first_stamp = float(entry['first_stamp'])
        self.last_stamp = float(entry.get('last_stamp', self.first_stamp))
        self.scan_stamps = np.array(entry.get('scan_stamps') or [], dtype=np.float64)
        # Pose of the first scan in the submap frame: the identity, except for the map's first
        # scan after the frame anchor re-expressed the session in that scan's frame.
        poses = entry.get('scan_poses') or []
        self.first_scan_pose = tr.pose_from_list(poses[0]) if poses else np.eye(4)
        self.points = int(entry.get('points', 0) or 0)
        self.file = os.path.join(map_dir, entry.get('file', 'submaps/%s/%d.pcd'
                                                    % (self.session, self.id)))
        self.status = str(entry.get('status', 'active'))

    @property
    def key(self):
        return (self.session, self.id)

    def load_points(self, origin=None):
        """Points of the submap in the map frame, (N, 3), placed at `origin` (4x4; default:
        the estimated origin)."""
        return tr.transform_points(self.origin if origin is None else origin,
                                   pcd.xyz(pcd.read_pcd(self.file)))


class LoopRow(object):
    def __init__(self, row):
        self.kind = row.get('kind', '')
        self.current_session = row.get('current_session', '')
        self.current_submap = int(row['current_submap'])
        self.history_session = row.get('history_session') or None
        hist = row.get('history_submap')
        self.history_submap = int(hist) if hist not in (None, '') else None
        self.status = row.get('status', '')
        self.vote_proportion = _float(row.get('vote_proportion'))
        self.overlap_ratio = _float(row.get('overlap_ratio'))
        # Since session 11; older maps have no such column.
        self.structure_overlap_ratio = _float(row.get('structure_overlap_ratio'))
        pose = [_float(row.get(k)) for k in ('tx', 'ty', 'tz', 'qx', 'qy', 'qz', 'qw')]
        self.pose = tr.pose_from_list(pose) if None not in pose else None
        self.reason = row.get('reason', '')


class PlaceRecognitionRow(object):
    def __init__(self, row):
        self.stamp = float(row['stamp'])
        self.submap = int(row['submap']) if row.get('submap') not in (None, '') else None
        self.matched = str(row.get('matched', '0')).strip() in ('1', 'true', 'True')
        self.history_session = row.get('history_session') or None
        self.history_stamp = _float(row.get('history_stamp'))
        self.distance = _float(row.get('distance'))
        self.top_k = []
        for item in (row.get('top_k') or '').split(';'):
            parts = item.strip().rsplit(':', 2)
            if len(parts) == 3 and parts[1] and parts[2]:
                self.top_k.append((parts[0], float(parts[1]), float(parts[2])))


class MapDir(object):
    """The pipeline's map directory."""

    def __init__(self, path):
        self.path = path
        manifest = _load_yaml(os.path.join(path, 'manifest.yaml'))
        self.manifest = manifest
        self.format_version = manifest.get('format_version')
        self.sessions = [dict(s) for s in manifest.get('sessions') or []]
        self.session_names = [str(s['name']) for s in self.sessions]
        self.submaps = [Submap(e, path) for e in manifest.get('submaps') or []]
        self.parameters = manifest.get('parameters') or {}

    def submaps_of(self, session):
        return [s for s in self.submaps if s.session == session]

    def trajectory(self, session):
        path = os.path.join(self.path, 'trajectories', '%s.tum' % session)
        return tr.read_tum(path) if os.path.isfile(path) else None

    def loops(self, session):
        rows = []
        for row in _read_csv(os.path.join(self.path, 'loops', '%s.csv' % session)):
            try:
                rows.append(LoopRow(row))
            except (KeyError, ValueError):
                raise EvalInputError('malformed row in loops/%s.csv: %s' % (session, row)) \
                    from None
        return rows

    def has_loops(self, session):
        return os.path.isfile(os.path.join(self.path, 'loops', '%s.csv' % session))

    def place_recognition(self, session):
        path = os.path.join(self.path, 'place_recognition', '%s.csv' % session)
        if not os.path.isfile(path):
            return None
        return [PlaceRecognitionRow(r) for r in _read_csv(path)]

    def timing(self, session):
        path = os.path.join(self.path, 'timing', '%s.yaml' % session)
        return _load_yaml(path) if os.path.isfile(path) else None

    def removed_points(self, session):
        path = os.path.join(self.path, 'dynamics', '%s_removed.pcd' % session)
        return pcd.xyz(pcd.read_pcd(path)) if os.path.isfile(path) else None


class Truth(object):
    """The simulator's ground truth."""

    def __init__(self, path):
        self.path = path
        self.index = _load_yaml(os.path.join(path, 'sessions.yaml'))
        world_path = os.path.join(path, 'world.yaml')
        # No metric needs the terrain grid, object parts or moving-object trajectories (only
        # whether an object has one): those blocks read as 'omitted' (a much faster parse).
        self.world = (_load_yaml(world_path, omit_blocks=('terrain', 'parts', 'trajectory'))
                      if os.path.isfile(world_path) else {'objects': []})
        self.sessions = {str(s['name']): s for s in self.index.get('sessions') or []}
        self.session_names = [str(s['name']) for s in self.index.get('sessions') or []]
        self._trajectories = {}

    def resolve(self, map_session):
        """Truth session name for a map session: same name, else same bag basename."""
        if map_session in self.sessions:
            return map_session
        for name, entry in self.sessions.items():
            bag = os.path.splitext(os.path.basename(str(entry.get('bag', ''))))[0]
            if bag == map_session:
                return name
        return None

    def trajectory(self, name):
        if name not in self._trajectories:
            entry = self.sessions.get(name, {})
            rel = entry.get('truth_trajectory', 'truth/%s.tum' % name)
            path = os.path.join(self.path, rel)
            if not os.path.isfile(path):
                raise EvalInputError('missing ground-truth trajectory: %s' % path)
            self._trajectories[name] = tr.read_tum(path)
        return self._trajectories[name]

    def labels(self, name):
        """(points (N,3) world frame, label (N,), object_id (N,), range (N,) or None) or None
        when absent. range: the smallest sensor range at which the point's voxel was measured
        (simulator field `range`; None in truth written before it existed)."""
        entry = self.sessions.get(name, {})
        path = os.path.join(self.path, entry.get('labels', 'truth/%s_labels.pcd' % name))
        if not os.path.isfile(path):
            return None
        cloud = pcd.read_pcd(path)
        ranges = (np.asarray(cloud['range']).astype(np.float64) if 'range' in cloud else None)
        return (pcd.xyz(cloud), np.asarray(cloud['label']).astype(np.int64),
                np.asarray(cloud['object_id']).astype(np.int64), ranges)

    @property
    def objects(self):
        return self.world.get('objects') or []


def directory_bytes(path):
    total = 0
    for root, _, files in os.walk(path):
        for name in files:
            full = os.path.join(root, name)
            if os.path.isfile(full) and not os.path.islink(full):
                total += os.path.getsize(full)
    return total
