#!/usr/bin/env python3
"""Markdown table of bench/real_noise_pairs.sh output (JSON lines, run with KS=...): per scene the raw mesh, the
default stereo path (covariances kept), the default generic path (no covariances, k estimated), the best k of the
KS sweep in hindsight and the default's ratio to it; then per split the share of scenes within 5% and the worst.
Lines for a mesh named old.ply (the same JSON, any k) fill an extra column: an earlier estimate to compare with.
    bench/real_noise_table.py RESULTS.jsonl [RESULTS.jsonl ...]"""
import collections
import json
import sys

pairs, cov, generic, old, sweep, split = {}, {}, {}, {}, collections.defaultdict(dict), {}
for path in sys.argv[1:]:
    for line in open(path):
        r = json.loads(line)
        if 'pair' in r:
            s = r['pair']['scene'].split('/stereo/')[-1]
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
    print(f"| {split[s]} | {s.split('/')[-1]} ({s.split('/')[0].replace('middlebury_', '')}) | {p['faces']} "
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
