#!/usr/bin/python3
"""The generic smoothing path on real laser scans: the ten Stanford bunny range scans (Cyberware, posed by their
bun.conf) smoothed as plain meshes (their covariances ignored, k estimated, as `rangebayes smooth scan.ply out.ply
--ignore-covariance` does), and at the single k values of a sweep, scored against the zippered Stanford bunny. A second real sensor beside the
stereo pairs of bench/real_noise_pairs.sh, held out from every choice of the noise estimate.

Reference surface: GuidedDenoising's copy of the zippered bunny (models/Bunny0.2/Original.obj, normalised to a unit
box), aligned back onto the posed scans by a similarity ICP from the best of the 24 axis-aligned starts. Score per
scan: mean angle between each face's normal (in the bun.conf frame) and the normal of the reference face nearest
to its centroid, over the faces whose centroid lies within one reference edge of a reference face centroid (the
same faces for every result). The reference is coarser than the scans (edge about 1.5 mm against 0.85 mm) and made
from them, so it favours smoothing a little; the comparison between k values is what the benchmark is for.

    PYTHONPATH=build/release/python bench/real_scan_pairs.py [--shared ../shared] [--ks 0.1,0.2,...] > scans.jsonl

One JSON line per scan: faces scored, the estimated k, raw, file_covariances (the range grid's own ray covariances,
the `smooth` default for these files), default (the generic model with the estimated k) and one entry per k; a last
line with how many scans the generic default has within 5% of the best k of the sweep in hindsight.
"""
import argparse
import itertools
import json
import os
import sys

import numpy as np
from scipy.spatial import cKDTree

import rangebayes as rb


def rotation(x, y, z, w):
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_poses(conf):
    """bun.conf: `bmesh FILE tx ty tz qx qy qz qw`; a scan point p lies at R(q)ᵀ p + t, the convention of fusion's
    ReadScanPoses (the scans then overlap to 0.3 mm median)."""
    poses = {}
    for line in open(conf):
        f = line.split()
        if f and f[0] == 'bmesh':
            t = np.array([float(v) for v in f[2:5]])
            qx, qy, qz, qw = (float(v) for v in f[5:9])
            poses[os.path.splitext(f[1])[0]] = (rotation(-qx, -qy, -qz, qw), t)
    return poses


def similarity_icp(points, tree, iterations):
    """Umeyama similarity steps onto the nearest tree points, the farthest 20% of pairs left out each step."""
    for _ in range(iterations):
        d, i = tree.query(points)
        keep = d < np.quantile(d, 0.8)
        p, q = points[keep], tree.data[i[keep]]
        mp, mq = p.mean(0), q.mean(0)
        u, s, vt = np.linalg.svd((q - mq).T @ (p - mp) / len(p))
        sign = np.eye(3)
        if np.linalg.det(u @ vt) < 0:
            sign[2, 2] = -1
        r = u @ sign @ vt
        scale = np.trace(np.diag(s) @ sign) / ((p - mp) ** 2).sum(1).mean()
        points = scale * points @ r.T + (mq - scale * r @ mp)
    return points


def align_reference(reference, union):
    tree = cKDTree(union[::3])
    centre = (union.min(0) + union.max(0)) / 2
    size = np.linalg.norm(union.max(0) - union.min(0))
    ref_centre = (reference.min(0) + reference.max(0)) / 2
    ref_size = np.linalg.norm(reference.max(0) - reference.min(0))
    best = None
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product([1, -1], repeat=3):
            m = np.zeros((3, 3))
            for a, b in enumerate(perm):
                m[a, b] = signs[a]
            if np.linalg.det(m) < 0:
                continue
            start = (reference - ref_centre) @ m.T * (size / ref_size) + centre
            moved = similarity_icp(start, tree, 15)
            median = np.median(tree.query(moved)[0])
            if best is None or median < best[0]:
                best = (median, moved)
    moved = similarity_icp(best[1], tree, 40)
    return moved, np.median(tree.query(moved)[0])


def face_normals(v, f):
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(n, axis=1)
    return n / np.maximum(length, 1e-300)[:, None], length


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--shared', default=os.path.join(os.path.dirname(__file__), '..', '..', 'shared'))
    parser.add_argument('--ks', default='0.1,0.2,0.25,0.3,0.4,0.5,0.7')
    args = parser.parse_args()
    scans_dir = os.path.join(args.shared, 'data', 'scans', 'stanford_bunny')
    reference_path = os.path.join(args.shared, 'data', 'meshes', 'guideddenoising', 'bunny_gt.obj')
    for path in (os.path.join(scans_dir, 'bun.conf'), reference_path):
        if not os.path.isfile(path):
            sys.exit(f'real_scan_pairs: error: {path} not found (give --shared)')
    try:
        ks = [float(k) for k in args.ks.split(',')]
    except ValueError:
        sys.exit(f'real_scan_pairs: error: --ks {args.ks!r} is not a comma-separated list of numbers')

    poses = read_poses(os.path.join(scans_dir, 'bun.conf'))
    scans = {name: rb.read_mesh(os.path.join(scans_dir, name + '.ply')) for name in poses}
    world = {name: (lambda v, r=r, t=t: v @ r.T + t) for name, (r, t) in poses.items()}
    union = np.vstack([world[n](np.asarray(m.V)) for n, m in scans.items()])
    reference = rb.read_mesh(reference_path)
    ref_v, distance = align_reference(np.asarray(reference.V, dtype=float), union)
    ref_f = np.asarray(reference.F)
    print(f'reference aligned: median distance to the scans {distance * 1e3:.3f} mm', file=sys.stderr)
    ref_n, _ = face_normals(ref_v, ref_f)
    ref_tree = cKDTree(ref_v[ref_f].mean(1))
    ref_edge = np.mean(np.linalg.norm(ref_v[ref_f[:, 0]] - ref_v[ref_f[:, 1]], axis=1))

    within = 0
    for name, mesh in scans.items():
        faces = np.asarray(mesh.F)

        def cosines(vertices, mask=None):
            posed = world[name](np.asarray(vertices))
            n, area = face_normals(posed, faces)
            d, i = ref_tree.query(posed[faces].mean(1))
            if mask is None:
                mask = (d < ref_edge) & (area > 0)
            return mask, np.sum(n[mask] * ref_n[i[mask]], 1)

        mask, c = cosines(mesh.V)
        sign = 1.0 if c.mean() > 0 else -1.0  # the scan's faces may wind the other way round

        def angle(c):
            return float(np.degrees(np.arccos(np.clip(sign * c, -1, 1))).mean())

        row = {'scan': name, 'faces': int(mask.sum()), 'k_estimated': rb.estimate_noise_level(mesh), 'raw': angle(c)}
        result, _ = rb.smooth(mesh)  # the range grid's own ray covariances (what `rangebayes smooth scan.ply` uses)
        row['file_covariances'] = angle(cosines(result.V, mask)[1])
        result, _ = rb.smooth(mesh, ignore_covariance=True)
        row['default'] = angle(cosines(result.V, mask)[1])
        for k in ks:
            result, _ = rb.smooth(mesh, noise=k)
            row[f'{k:g}'] = angle(cosines(result.V, mask)[1])
        best = min(row[f'{k:g}'] for k in ks)
        row['ratio'] = row['default'] / best
        within += row['ratio'] <= 1.05
        print(json.dumps(row), flush=True)
    print(json.dumps({'scans': len(scans), 'default_within_5_percent_of_best_k': within}))


if __name__ == '__main__':
    main()
