#!/usr/bin/python3
"""The per-scene table of BENCHMARKS.md "Smoothing on real stereo" from the JSON lines of
bench/stereo_smooth_scenes.sh:  bench/stereo_smooth_table.py scenes.jsonl [REFERENCES.jsonl]

REFERENCES.jsonl: stored reference solves (scene, reference summary, normal_deg, depth_mae_mm), used instead of
the run's own (bench/stereo_smooth_references_q4.jsonl: every 4th pixel, made once; BENCHMARKS.md says how)."""
import json
import re
import sys


def energy(line):
    return float(re.search(r"energy:\s+\S+ -> (\S+)", line).group(1))


def evaluations(line):
    return int(re.search(r"(\d+) evaluations", line).group(1))


rows, current = [], None
for text in open(sys.argv[1]):
    record = json.loads(text)
    if "stereo_s" in record:
        current = {"scene": record["scene"], "stereo_s": record["stereo_s"], "smooth_s": record["smooth_s"],
                   "e_default": energy(record["smooth"]), "evals_default": evaluations(record["smooth"])}
        if record["reference"]:  # empty with NO_REFERENCE=1 (then stored references are needed)
            current["e_reference"] = energy(record["reference"])
            current["evals_reference"] = evaluations(record["reference"])
        rows.append(current)
    else:
        kind = record["mesh"].rsplit("/", 1)[1].split(".")[0]
        current[kind] = (record["normal_deg"], record["depth_mae_mm"])

if len(sys.argv) > 2:
    stored = {r["scene"]: r for r in map(json.loads, open(sys.argv[2]))}
    for r in rows:
        ref = stored[r["scene"]]
        r["e_reference"], r["evals_reference"] = energy(ref["reference"]), evaluations(ref["reference"])
        r["reference"] = (ref["normal_deg"], ref["depth_mae_mm"])

print("| scene | raw ° / mm | default ° / mm | reference ° / mm | SGBM + bilateral ° / mm | default / peer normal "
      "| E default vs reference | Δ normal default − ref | final-solve evaluations default / reference "
      "| stereo s / smooth s (ratio) |")
print("|---|---|---|---|---|---|---|---|---|---|")
gaps, ratios, deltas, times = [], [], [], []
for r in rows:
    gap = (r["e_default"] - r["e_reference"]) / r["e_reference"]
    ratio = r["smoothed"][0] / r["bilateral"][0]
    delta = r["smoothed"][0] - r["reference"][0]
    time_ratio = r["smooth_s"] / r["stereo_s"]
    gaps.append(gap), ratios.append(ratio), deltas.append(delta), times.append(time_ratio)
    cell = lambda k: "%.2f / %.1f" % r[k]
    print("| %s | %s | %s | %s | %s | %.2f | %+.2f%% | %+.2f° | %d / %d | %.2f / %.2f (%.1f×) |" % (
        r["scene"], cell("mesh"), cell("smoothed"), cell("reference"), cell("bilateral"), ratio, 100 * gap, delta,
        r["evals_default"], r["evals_reference"], r["stereo_s"], r["smooth_s"], time_ratio))
gaps_sorted = sorted(gaps)
print("\nscenes %d; E above reference: max %.2f%%, median %.2f%%, within 0.1%%: %d; |Δ normal| max %.2f°; "
      "default/peer normal max %.2f mean %.2f; smooth/stereo wall ratio %.1f–%.1f×" % (
          len(rows), 100 * max(gaps), 100 * gaps_sorted[len(gaps) // 2], sum(g <= 0.001 for g in gaps),
          max(abs(d) for d in deltas), max(ratios), sum(ratios) / len(ratios), min(times), max(times)))
