#!/usr/bin/env python3
"""Publishes a stored map directory (or a small synthetic scene) on the topics that
rviz/mapping.rviz shows, so that RViz can be looked at or screenshotted without running the
nodelets: merged_map (PointCloud2), submaps (SubmapInfo), loop_candidates (LoopCandidateArray,
from loops/<session>.csv), dynamic_points (DynamicPoints, from dynamics/<session>_*.pcd),
path (nav_msgs/Path: the last session's trajectory) and change_summary (std_msgs/String).

  rviz_publish_map.py --map DIR [--voxel 0.3] [--duration S]
  rviz_publish_map.py --synthetic [--duration S]

Needs the workspace's devel/setup.bash sourced (messages and multisession_mapper_eval).
Exits after --duration seconds (0: until killed).
"""
import argparse
import os
import sys

import numpy as np
import rospy
import yaml
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import Path
from multisession_mapper.msg import DynamicPoints, LoopCandidate, LoopCandidateArray, SubmapInfo
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Header, String

STATUS = {'candidate': LoopCandidate.CANDIDATE, 'accepted': LoopCandidate.ACCEPTED,
          'rejected': LoopCandidate.REJECTED, 'undefined': LoopCandidate.UNDEFINED}


def cloud_msg(points, header):
    """PointCloud2 with float32 x, y, z from an (N, 3) array."""
    points = np.ascontiguousarray(np.asarray(points, dtype=np.float32).reshape(-1, 3))
    msg = PointCloud2(header=header, height=1, width=len(points), is_bigendian=False,
                      point_step=12, row_step=12 * len(points), is_dense=True)
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate('xyz')]
    msg.data = points.tobytes()
    return msg


def voxel_downsample(points, voxel_m):
    if len(points) == 0 or voxel_m <= 0:
        return points
    _, first = np.unique(np.floor(points / voxel_m).astype(np.int64), axis=0, return_index=True)
    return points[np.sort(first)]


def point(xyz):
    return Point(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))


class Scene(object):
    """Everything to publish: plain data, filled from a map directory or synthesised."""

    def __init__(self):
        self.map_points = np.zeros((0, 3))
        self.submaps = []    # (session, id, origin xyz, num_points)
        self.loops = []      # (LoopCandidate, current origin xyz, history origin xyz or None)
        self.dynamics = []   # (session, removed (N,3), mended (M,3), held (K,3))
        self.summary = ''
        self.path = np.zeros((0, 3))  # positions of the last session's trajectory, map frame


def scene_from_map(map_dir, voxel_m):
    # The evaluator's reader of the map format (python/multisession_mapper_eval/io.py).
    from multisession_mapper_eval import io as map_io, pcd
    m = map_io.MapDir(map_dir)
    scene = Scene()
    origins = {}
    clouds = []
    for s in m.submaps:
        origins[s.key] = s.origin[:3, 3]
        if s.status != 'active':
            continue
        clouds.append(voxel_downsample(s.load_points(), voxel_m))
        scene.submaps.append((s.session, s.id, s.origin[:3, 3], s.points))
    if clouds:
        scene.map_points = voxel_downsample(np.concatenate(clouds), voxel_m)
    counts = dict((k, 0) for k in STATUS)
    for session in m.session_names:
        for row in m.loops(session):
            status = STATUS.get(row.status)
            current = origins.get((row.current_session, row.current_submap))
            if status is None or current is None:
                continue
            history = None
            if row.history_session is not None and row.history_submap is not None:
                history = origins.get((row.history_session, row.history_submap))
            c = LoopCandidate(current_session=row.current_session,
                              current_submap=row.current_submap,
                              history_session=row.history_session or '',
                              history_submap=row.history_submap or 0, status=status,
                              vote_proportion=row.vote_proportion or 0.0,
                              overlap_ratio=row.overlap_ratio or 0.0, reason=row.reason)
            scene.loops.append((c, current, history))
            counts[row.status] += 1
        dyn = os.path.join(map_dir, 'dynamics')
        files = [os.path.join(dyn, '%s_%s.pcd' % (session, kind))
                 for kind in ('removed', 'mended', 'held')]
        if any(os.path.isfile(f) for f in files):
            scene.dynamics.append((session,) + tuple(
                pcd.xyz(pcd.read_pcd(f)) if os.path.isfile(f) else np.zeros((0, 3))
                for f in files))
    trajectory = m.trajectory(m.session_names[-1]) if m.session_names else None
    if trajectory is not None:
        scene.path = trajectory.positions
    # The change record of the last merged session (changes/<session>.yaml), else changelog.yaml.
    changes = [os.path.join(map_dir, 'changes', '%s.yaml' % name) for name in m.session_names[-1:]]
    changes = [p for p in changes + [os.path.join(map_dir, 'changelog.yaml')] if os.path.isfile(p)]
    if changes:
        with open(changes[0]) as f:
            scene.summary = yaml.safe_dump(yaml.safe_load(f), default_flow_style=False,
                                           sort_keys=False)[:2000]
    else:
        scene.summary = ('%s: %d sessions, %d submaps; loops: %s'
                         % (os.path.basename(os.path.normpath(map_dir)), len(m.session_names),
                            len(m.submaps), ', '.join('%d %s' % (n, k)
                                                      for k, n in counts.items())))
    return scene


def synthetic_scene():
    """A 60 m x 60 m ground grid, four loops (one per status) and one removed/mended/held block."""
    scene = Scene()
    g = np.arange(-30.0, 30.0, 0.5)
    gx, gy = np.meshgrid(g, g)
    scene.map_points = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], axis=1)
    origins = [np.array([x, y, 0.0]) for x, y in ((-20, -20), (20, -20), (20, 20), (-20, 20))]
    for i, o in enumerate(origins):
        scene.submaps.append(('s00', i, o, 1000))
        scene.submaps.append(('s01', i, o + [8.0, 6.0, 0.0], 1000))
    for status, name in enumerate(('candidate', 'accepted', 'rejected', 'undefined')):
        undefined = name == 'undefined'
        c = LoopCandidate(current_session='s01', current_submap=status,
                          history_session='' if undefined else 's00',
                          history_submap=0 if undefined else status, status=status,
                          vote_proportion=0.25 * (status + 1), overlap_ratio=0.2 * status)
        scene.loops.append((c, origins[status] + [8.0, 6.0, 0.0],
                            None if undefined else origins[status]))
    b = np.arange(-3.0, 3.0, 0.1)
    bx, by = np.meshgrid(b, b)
    block = np.stack([bx.ravel(), by.ravel(), np.full(bx.size, 1.0)], axis=1)
    scene.dynamics.append(('s01', block, block + [8.0, 0.0, 0.0], block + [-8.0, 0.0, 0.0]))
    scene.path = np.array([o + [8.0, 6.0, 0.0] for o in origins])
    scene.summary = 'synthetic scene: 2 sessions, 8 submaps, 4 loops, %d removed points' % len(block)
    return scene


def wait_for_subscribers(publisher, timeout_s):
    deadline = rospy.get_time() + timeout_s
    while publisher.get_num_connections() == 0 and rospy.get_time() < deadline \
            and not rospy.is_shutdown():
        rospy.sleep(0.1)


def publish(scene, frame, subscriber_wait_s):
    header = Header(frame_id=frame, stamp=rospy.Time.now())
    latched = dict(latch=True, queue_size=1)
    map_pub = rospy.Publisher('merged_map', PointCloud2, **latched)
    loops_pub = rospy.Publisher('loop_candidates', LoopCandidateArray, **latched)
    summary_pub = rospy.Publisher('change_summary', String, **latched)
    path_pub = rospy.Publisher('path', Path, **latched)
    submaps_pub = rospy.Publisher('submaps', SubmapInfo, queue_size=max(1, len(scene.submaps)))
    dynamic_pub = rospy.Publisher('dynamic_points', DynamicPoints,
                                  queue_size=max(1, len(scene.dynamics)))

    map_pub.publish(cloud_msg(scene.map_points, header))
    loops = LoopCandidateArray(header=header)
    for c, current, history in scene.loops:
        loops.candidates.append(c)
        loops.current_origins.append(point(current))
        loops.history_origins.append(point(history if history is not None else current))
    loops_pub.publish(loops)
    summary_pub.publish(String(data=scene.summary))
    path = Path(header=header)
    for xyz in scene.path:
        pose = PoseStamped(header=header)
        pose.pose.position = point(xyz)
        pose.pose.orientation.w = 1.0
        path.poses.append(pose)
    path_pub.publish(path)

    # Several messages each: sent once the viewer is subscribed (not latched).
    wait_for_subscribers(submaps_pub, subscriber_wait_s)
    for session, submap_id, origin, num_points in scene.submaps:
        info = SubmapInfo(header=header, session=session, id=submap_id, num_points=num_points)
        info.origin.position = point(origin)
        info.origin.orientation.w = 1.0
        submaps_pub.publish(info)
        rospy.sleep(0.002)
    wait_for_subscribers(dynamic_pub, subscriber_wait_s)
    for session, removed, mended, held in scene.dynamics:
        dynamic_pub.publish(DynamicPoints(header=header, current_session=session,
                                          removed=cloud_msg(removed, header),
                                          mended=cloud_msg(mended, header),
                                          held=cloud_msg(held, header)))
    rospy.loginfo('published %d map points, %d submaps, %d loops, %d dynamic point sets, '
                  '%d path poses', len(scene.map_points), len(scene.submaps), len(scene.loops),
                  len(scene.dynamics), len(scene.path))
    return [map_pub, loops_pub, summary_pub, path_pub, submaps_pub, dynamic_pub]


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument('--map', help='map directory written by offline_mapper or the nodelets')
    source.add_argument('--synthetic', action='store_true', help='publish a synthetic scene')
    parser.add_argument('--frame', default='map', help='frame of every message')
    parser.add_argument('--voxel', type=float, default=0.3, help='map cloud voxel size [m]')
    parser.add_argument('--subscriber-wait', type=float, default=30.0,
                        help='how long to wait for RViz to subscribe [s]')
    parser.add_argument('--duration', type=float, default=0.0,
                        help='exit after this many seconds (0: until killed)')
    args = parser.parse_args(rospy.myargv(argv)[1:])
    if args.map and not os.path.isfile(os.path.join(args.map, 'manifest.yaml')):
        parser.error('%s has no manifest.yaml' % args.map)

    rospy.init_node('rviz_publish_map', anonymous=True)
    scene = synthetic_scene() if args.synthetic else scene_from_map(args.map, args.voxel)
    publishers = publish(scene, args.frame, args.subscriber_wait)
    if args.duration > 0:
        rospy.sleep(args.duration)
    else:
        rospy.spin()
    del publishers


if __name__ == '__main__':
    main(sys.argv)
