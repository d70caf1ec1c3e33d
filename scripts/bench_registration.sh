#!/usr/bin/env bash
# Runs the global-registration benchmark (cairn::register_global vs the same pipeline in PCL, and
# Open3D FPFH + RANSAC when built with it; same input, same run) and prints a table: ms per stage,
# totals, the speed-up of cairn over PCL, success and errors against the truth.
#   scripts/bench_registration.sh [build-dir] [results.json]
#     build-dir     default: build (a Release build with PCL found)
#     results.json  print the table of an earlier run (--benchmark_format=json output) instead
# The segmentation is shared: cairn segments both clouds once (timed as its stages
# segmentation_source/target) and PCL/Open3D start from those segments (PCL's own segmentation:
# scripts/bench.sh). The speed-up is given without the segmentation and with cairn's segmentation
# time added to both sides.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-build}
if [[ $# -ge 2 ]]; then
  out=$2
else
  out=$(mktemp --suffix=.json)
  trap 'rm -f "$out"' EXIT
  "$dir/bench/bench_registration" --benchmark_format=json --benchmark_out="$out" >/dev/null
fi
/usr/bin/python3 - "$out" <<'PY'
import json, sys
runs = {b["name"].split("/")[0][3:]: b for b in json.load(open(sys.argv[1]))["benchmarks"]}
cairn, pcl, o3d = runs.get("Cairn_RegisterGlobal"), runs.get("Pcl_Pipeline"), runs.get("Open3d_FpfhRansac")
if cairn is None or pcl is None:
    sys.exit("bench_registration: BM_Cairn_RegisterGlobal and BM_Pcl_Pipeline are needed")
ms = lambda b, s: b.get("ms_" + s) if b else None

# Rows: (label, cairn stage(s), PCL stage(s), Open3D stage(s)); stages of one row are summed.
rows = [
    ("segmentation (shared)", ["segmentation_source", "segmentation_target"], [], []),
    ("voxel grid", [], [], ["voxel"]),
    ("keypoints", ["keypoints"], ["keypoints"], []),
    ("normals", [], ["normals"], ["normals"]),
    ("descriptors", ["descriptors"], ["descriptors"], ["descriptors"]),
    ("matching", ["matching"], ["matching"], []),
    ("grouping/verification", ["verification"], ["grouping"], ["ransac"]),
    ("refinement (ICP)", ["refinement"], ["icp"], ["icp"]),
    ("merge", ["merge"], [], []),
]
def cell(b, stages):
    if b is None or not stages: return ""
    v = [ms(b, s) for s in stages]
    return "" if any(x is None for x in v) else f"{sum(v):.1f}"

print(f"{'stage [ms]':<28}{'cairn':>12}{'PCL':>12}{'Open3D':>12}")
for label, c, p, o in rows:
    print(f"{label:<28}{cell(cairn, c):>12}{cell(pcl, p):>12}{cell(o3d, o):>12}")
print("  (cairn keypoints include its kd-tree and normals; its segmentation_source the source voxel grid and levelling)")
seg = ms(cairn, "segmentation_source") + ms(cairn, "segmentation_target")
merge = ms(cairn, "merge")
c_reg = cairn["ms_total"] - merge      # keypoints .. refinement
p_reg = pcl["ms_total"]
o_reg = o3d["ms_total"] if o3d else None
fmt = lambda x: "" if x is None else f"{x:.1f}"
print(f"{'total w/o segm., w/o merge':<28}{fmt(c_reg):>12}{fmt(p_reg):>12}{fmt(o_reg):>12}")
print(f"{'total w/o segm., merge, ICP':<28}{fmt(c_reg - ms(cairn, 'refinement')):>12}"
      f"{fmt(p_reg - ms(pcl, 'icp')):>12}{fmt(o_reg - ms(o3d, 'icp') if o3d else None):>12}")
print(f"{'total with segmentation':<28}{fmt(c_reg + seg + merge):>12}{fmt(p_reg + seg):>12}"
      f"{fmt(o_reg + seg if o3d else None):>12}")
print()
print(f"speed-up cairn vs PCL, without segmentation (cairn w/o merge): {p_reg / c_reg:.1f}x")
print(f"speed-up cairn vs PCL, with the shared segmentation (cairn incl. merge): "
      f"{(p_reg + seg) / (c_reg + seg + merge):.1f}x")
print(f"speed-up cairn vs PCL, without segmentation, merge and ICP: "
      f"{(p_reg - ms(pcl, 'icp')) / (c_reg - ms(cairn, 'refinement')):.1f}x")
# PCL's timed ICP starts from its own (usually wrong) best group: it runs to the iteration cap or
# stops at once, so its cost says little. The like-for-like figure gives it the refinement cairn
# does, from the right start (the truth).
p_like = p_reg - ms(pcl, "icp") + pcl["icp_from_truth_ms"]
print(f"speed-up cairn vs PCL, without segmentation, PCL's ICP started at the truth: {p_like / c_reg:.1f}x")
if o3d:
    print(f"speed-up cairn vs Open3D, without segmentation (cairn w/o merge): {o_reg / c_reg:.1f}x")
print()
print(f"{'result':<28}{'cairn':>12}{'PCL':>12}{'Open3D':>12}")
for key, label, f in [("success", "success (own test)", "{:.0f}"), ("correct", "within 2 deg / 10 cm", "{:.0f}"),
                      ("rotation_deg", "rotation error [deg]", "{:.3f}"),
                      ("translation_m", "translation error [mm]", "{:.1f}"),
                      ("object_points", "object-segment points", "{:.0f}"),
                      ("keypoints", "keypoints", "{:.0f}"),
                      ("correspondences", "correspondences", "{:.0f}")]:
    vals = []
    for b in (cairn, pcl, o3d):
        v = b.get(key) if b else None
        if v is None and b is not cairn and key == "object_points": v = b.get("points") if b else None
        if v is not None and key == "translation_m": v *= 1000
        vals.append("" if v is None else f.format(v))
    print(f"{label:<28}{vals[0]:>12}{vals[1]:>12}{vals[2]:>12}")
print("  (PCL and Open3D have no acceptance test of their own: their success is 'within 2 deg / 10 cm')")
print()
if "accepted_from_centroids" in cairn:
    print(f"cairn: accepted alignment from {'centroid-pair hypotheses' if cairn['accepted_from_centroids'] else 'a consistency group'}"
          f" ({cairn['candidates']:.0f} consistency groups, {cairn['matched_segments']:.0f} matched segments)")
print(f"PCL: {pcl['clusters']:.0f} consistency groups, best has {pcl['best_cluster']:.0f} correspondences, "
      f"{pcl['clusters_near_truth']:.0f} within 10 deg / 1 m of the truth; ICP {pcl['icp_iterations']:.0f} iterations "
      f"(from the truth: {pcl['icp_from_truth_iterations']:.0f} iterations, {pcl['icp_from_truth_ms']:.0f} ms)")
if o3d:
    print(f"Open3D: {o3d['voxelised_points']:.0f} voxelised points, RANSAC fitness {o3d['ransac_fitness']:.3f}, "
          f"{o3d['ransac_inliers']:.0f} inliers")
PY
