"""PNG figures (matplotlib, Agg backend; no display needed)."""

import os

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

_COLORS = plt.get_cmap('tab10').colors


def _subsample(points, max_points, seed=0):
    if len(points) <= max_points:
        return points
    rng = np.random.default_rng(seed)
    return points[rng.choice(len(points), max_points, replace=False)]


def _figsize(point_sets, width=10.0):
    """A figure whose aspect follows the data's x/y extent (clamped)."""
    sets = [p for p in point_sets if p is not None and len(p)]
    if not sets:
        return (width, width)
    allp = np.vstack([p[:, :2] for p in sets])
    extent = np.ptp(allp, axis=0) + 1e-6
    return (width, float(np.clip(width * extent[1] / extent[0], 4.0, 14.0)))


def map_top_view(path, session_points, removed_points, max_points=200000):
    """Merged map from above coloured by session; removed dynamic points in red."""
    fig, ax = plt.subplots(figsize=_figsize(list(session_points.values())))
    total = max(1, sum(len(p) for p in session_points.values()))
    for i, (name, points) in enumerate(session_points.items()):
        share = max(1000, int(max_points * len(points) / total))
        pts = _subsample(points, share, seed=i)
        if len(pts):
            ax.scatter(pts[:, 0], pts[:, 1], s=0.2, color=_COLORS[(i + 1) % 10], label=name,
                       rasterized=True, linewidths=0)
    if removed_points is not None and len(removed_points):
        pts = _subsample(removed_points, max_points // 4, seed=99)
        ax.scatter(pts[:, 0], pts[:, 1], s=1.0, color='red', label='removed dynamic',
                   rasterized=True, linewidths=0)
    ax.set_aspect('equal', adjustable='datalim')
    ax.set_xlabel('x [m] (map frame)')
    ax.set_ylabel('y [m]')
    ax.set_title('Merged map (active submaps)')
    ax.legend(markerscale=15, loc='upper left', bbox_to_anchor=(1.0, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def trajectories(path, estimated, truth):
    """Estimated (solid) vs ground-truth (dashed) trajectories, map frame, from above."""
    fig, ax = plt.subplots(figsize=_figsize(list(truth.values())))
    for i, name in enumerate(truth):
        color = _COLORS[(i + 1) % 10]
        t = truth[name]
        ax.plot(t[:, 0], t[:, 1], '--', color=color, linewidth=1, label='%s truth' % name)
        e = estimated.get(name)
        if e is not None and len(e):
            ax.plot(e[:, 0], e[:, 1], '-', color=color, linewidth=1.5, alpha=0.7,
                    label='%s estimate' % name)
    ax.set_aspect('equal', adjustable='datalim')
    ax.set_xlabel('x [m] (map frame)')
    ax.set_ylabel('y [m]')
    ax.set_title('Trajectories vs ground truth (no alignment)')
    ax.legend(loc='upper left', bbox_to_anchor=(1.0, 1.0), fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def pr_curves(path, curves):
    """curves: session name -> {'precision': [...], 'recall': [...]}."""
    fig, ax = plt.subplots(figsize=(6, 5))
    plotted = 0
    for i, (name, curve) in enumerate(curves.items()):
        if curve['recall']:
            ax.plot(curve['recall'], curve['precision'], '-', color=_COLORS[(i + 1) % 10],
                    label=name)
            plotted += 1
    ax.set_xlim(0, 1.02)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel('recall')
    ax.set_ylabel('precision')
    ax.set_title('Place recognition (top-1, over the descriptor distance)')
    ax.grid(True, alpha=0.3)
    if plotted:
        ax.legend(loc='lower left')
    else:
        ax.text(0.5, 0.5, 'no place-recognition data', ha='center', va='center')
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def loop_table(path, sessions):
    """Stacked bars per new session: correct, undefined new, undefined missed, wrong."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    names = [s['name'] for s in sessions]
    bottom = np.zeros(len(names))
    for key, label, color in (('submaps_correct', 'correct', '#2ca02c'),
                              ('submaps_undefined_new', 'undefined (new place)', '#9e9e9e'),
                              ('submaps_undefined_missed', 'undefined (missed)', '#ff7f0e'),
                              ('submaps_wrong', 'wrong', '#d62728')):
        values = np.array([s[key] for s in sessions], dtype=float)
        ax.bar(names, values, bottom=bottom, label=label, color=color)
        bottom += values
    ax.set_ylabel('submaps')
    ax.set_title('Inter-session loop closure per session')
    ax.legend(loc='best', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_all(out_dir, data):
    """data: dict with map_points, removed, est_traj, truth_traj, pr_curves, sessions."""
    files = []
    if data.get('map_points') is not None:
        files.append(os.path.join(out_dir, 'map_top.png'))
        map_top_view(files[-1], data['map_points'], data.get('removed'))
    files.append(os.path.join(out_dir, 'trajectories.png'))
    trajectories(files[-1], data['est_traj'], data['truth_traj'])
    files.append(os.path.join(out_dir, 'place_recognition_pr.png'))
    pr_curves(files[-1], data['pr_curves'])
    files.append(os.path.join(out_dir, 'loop_table.png'))
    loop_table(files[-1], data['sessions'])
    return [os.path.basename(f) for f in files]
