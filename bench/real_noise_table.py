#!/usr/bin/env python3
"""Markdown table of bench/real_noise_pairs.sh output (JSON lines, run with KS=...): per scene the raw mesh, the
default stereo path (covariances kept), the default generic path (no covariances, k estimated), the best k of the
KS sweep in hindsight and the default's ratio to it; then per split the share of scenes within 5% and the worst.
Lines for a mesh named old.ply (the same JSON, any k) fill an extra column: an earlier estimate to compare with.
--compare: two runs of bench/smooth_pairs.sh on the same pairs (e.g. no flags and "--prior prior.yaml"), per scene
BASE and OTHER normal error / depth MAE and the ratio of the normal errors, then how often OTHER is better.
    bench/real_noise_table.py RESULTS.jsonl [RESULTS.jsonl ...]
    bench/real_noise_table.py --compare BASE.jsonl OTHER.jsonl"""
import collections
import json
import statistics
import sys


def compare(base_path, other_path):
    runs = []
    for path in (base_path, other_path):
        runs.append({r['pair'].rstrip('/'): r for r in map(json.loads, open(path))})
    base, other = runs
    print(f"| scene | {base_path} ° / mm | {other_path} ° / mm | ° ratio |")
    print('|---|---|---|---|')
    ratios, depth_no_worse = [], 0
    for pair, b in base.items():
        if pair not in other:
            continue
        b, o = b['score'], other[pair]['score']
        ratio = o['normal_deg'] / b['normal_deg']
        ratios.append(ratio)
        depth_no_worse += o['depth_mae_mm'] <= b['depth_mae_mm']
        print(f"| {pair.split('/')[-1]} | {b['normal_deg']:.2f} / {b['depth_mae_mm']:.1f} | "
              f"{o['normal_deg']:.2f} / {o['depth_mae_mm']:.1f} | {ratio:.3f} |")
    print()
    print(f"{len(ratios)} scenes: normal error lower on {sum(r < 1 for r in ratios)}, depth MAE no worse on "
          f"{depth_no_worse}; ratio mean {statistics.mean(ratios):.3f}, median {statistics.median(ratios):.3f}, "
          f"range {min(ratios):.3f}-{max(ratios):.3f}")


if len(sys.argv) == 4 and sys.argv[1] == '--compare':
    compare(sys.argv[2], sys.argv[3])
    sys.exit(0)

pairs, cov, generic, old, sweep, split = {}, {}, {}, {}, collections.defaultdict(dict), {}
for path in sys.argv[1:]:
    for line in open(path):
        r = json.loads(line)
        if 'pair' in r:
            s = r.get('scene', r['pair']['scene'].split('/stereo/')[-1])
            pairs[s] = r['pair']
            split[s] = r['split']
            continue
        s, score = r['scene'], r['score']
        if score['mesh'].endswith('/stereo_default.ply'):
            cov[s] = score
        elif score['mesh'].endswith('/old.ply'):
            old[s] = (float(r['k']), score)
        elif score['mesh'].endswith('/generic_default.ply'):
            generic[s] = (float(r['k']), score)
        else:
            sweep[s][float(r['k'])] = score

print('| split | scene | faces (dropped) | raw ° / mm | stereo default ° / mm | generic default: k̂, ° / mm | '
      'hindsight best k, ° | default / best |' + (' old k̂, ° (/ best) |' if old else ''))
print('|---|---|---|---|---|---|---|---|' + ('---|' if old else ''))
summary = collections.defaultdict(list)
for s in pairs:
    if s not in generic or not sweep[s]:
        continue
    p, c, (k, g) = pairs[s], cov[s], generic[s]
    best_k = min(sweep[s], key=lambda x: sweep[s][x]['normal_deg'])
    best = min([sweep[s][best_k]['normal_deg'], g['normal_deg']] + ([old[s][1]['normal_deg']] if s in old else []))
    ratio = g['normal_deg'] / best
    summary[split[s]].append((ratio, s))
    layout = s.split('/')[0].replace('middlebury_', '') if '/' in s else 'D435, Gray-code pseudo ground truth'
    print(f"| {split[s]} | {s.split('/')[-1]} ({layout}) | {p['faces']} "
          f"({p['faces_dropped']}) | {p['raw_normal_deg']:.2f} / {p['raw_depth_mae_mm']:.1f} | "
          f"{c['normal_deg']:.2f} / {c['depth_mae_mm']:.1f} | {k:.3g}, {g['normal_deg']:.2f} / "
          f"{g['depth_mae_mm']:.1f} | {best_k:g}, {sweep[s][best_k]['normal_deg']:.2f} | {ratio:.3f} |" +
          (f" {old[s][0]:.3g}, {old[s][1]['normal_deg']:.2f} ({old[s][1]['normal_deg'] / best:.3f}) |" if s in old else
           (' |' if old else '')))
print()
for sp, rows in summary.items():
    worst = max(rows)
    within = sum(r <= 1.05 for r, _ in rows)
    print(f"{sp}: {within}/{len(rows)} scenes within 5% of the hindsight best; worst {worst[0]:.3f} "
          f"({worst[1].split('/')[-1]}); mean ratio {sum(r for r, _ in rows) / len(rows):.3f}")
