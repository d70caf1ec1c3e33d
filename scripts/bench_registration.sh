#!/usr/bin/env bash
# Runs the global-registration benchmark (cairn::register_global, also with candidates from the
# consistency groups only (no centroid-pair hypotheses), vs the paper's pipeline in PCL, and
# Open3D FPFH + RANSAC when built with it; same input, same run) and prints a table: ms per
# stage, totals, the speed-up of cairn over PCL, success and errors against the truth.
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
# The benchmarks are not part of the test build (scripts/test.sh): configure and build this one.
cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCAIRN_BUILD_BENCH=ON >/dev/null
cmake --build "$dir" --target bench_registration
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
cairn, groups, pcl, o3d = (runs.get(k) for k in ("Cairn_RegisterGlobal", "Cairn_GroupsOnly", "Pcl_Pipeline",
                                                 "Open3d_FpfhRansac"))
if cairn is None or pcl is None:
    sys.exit("bench_registration: BM_Cairn_RegisterGlobal and BM_Pcl_Pipeline are needed")
ms = lambda b, s: b.get("ms_" + s) if b else None
cols = [("cairn", cairn), ("cairn-groups", groups), ("PCL", pcl), ("Open3D", o3d)]

# Rows: (label, cairn stage(s), PCL stage(s), Open3D stage(s)); stages of one row are summed.
rows = [
    ("segmentation (shared)", ["segmentation_source", "segmentation_target"], [], []),
    ("voxel grid", [], [], ["voxel"]),
    ("keypoints", ["keypoints"], ["keypoints"], []),
    ("normals", [], ["normals"], ["normals"]),
    ("descriptors", ["descriptors"], ["descriptors"], ["descriptors"]),
    ("matching", ["matching"], ["matching"], []),
    ("grouping/verification", ["verification"], ["grouping", "verification"], ["ransac"]),
    ("refinement (ICP)", ["refinement"], ["icp"], ["icp"]),
    ("merge", ["merge"], [], []),
]
def cell(b, stages):
    if b is None or not stages: return ""
    v = [ms(b, s) for s in stages]
    return "" if any(x is None for x in v) else f"{sum(v):.1f}"
fmt = lambda x: "" if x is None else f"{x:.1f}"
line = lambda label, vals: print(f"{label:<28}" + "".join(f"{v:>13}" for v in vals))

line("stage [ms]", [c for c, _ in cols])
for label, c, p, o in rows:
    line(label, [cell(cairn, c), cell(groups, c), cell(pcl, p), cell(o3d, o)])
print("  (cairn keypoints include its kd-tree and normals; its segmentation_source the source voxel grid and levelling;")
print("   cairn-groups: the same without the centroid-pair hypotheses: candidates from consistency groups only, as PCL's)")
seg = ms(cairn, "segmentation_source") + ms(cairn, "segmentation_target")
reg = lambda b: None if b is None else b["ms_total"] - (ms(b, "merge") or 0.0)  # keypoints .. refinement
no_icp = lambda b, icp: None if b is None else reg(b) - ms(b, icp)
c_reg, a_reg, p_reg, o_reg = reg(cairn), reg(groups), reg(pcl), reg(o3d)
line("total w/o segm., w/o merge", [fmt(x) for x in (c_reg, a_reg, p_reg, o_reg)])
line("total w/o segm., merge, ICP", [fmt(no_icp(cairn, "refinement")), fmt(no_icp(groups, "refinement")),
                                      fmt(no_icp(pcl, "icp")), fmt(no_icp(o3d, "icp"))])
line("total with segmentation", [fmt(c_reg + seg + ms(cairn, "merge")),
                                  fmt(a_reg + ms(groups, "segmentation_source") + ms(groups, "segmentation_target")
                                      + ms(groups, "merge") if groups else None), fmt(p_reg + seg),
                                  fmt(o_reg + seg if o3d else None)])
print()
print(f"speed-up cairn vs PCL, without segmentation (cairn w/o merge): {p_reg / c_reg:.1f}x")
if groups:
    print(f"speed-up cairn-groups vs PCL, candidates from consistency groups in both, without segmentation and merge: "
          f"{p_reg / a_reg:.1f}x")
print(f"speed-up cairn vs PCL, with the shared segmentation (cairn incl. merge): "
      f"{(p_reg + seg) / (c_reg + seg + ms(cairn, 'merge')):.1f}x")
print(f"speed-up cairn vs PCL, without segmentation, merge and ICP: "
      f"{no_icp(pcl, 'icp') / no_icp(cairn, 'refinement'):.1f}x")
# PCL's timed ICP starts from its best-verified group, right or wrong, and its cost depends on
# where that is; this figure gives it the refinement cairn does, from the right start (the truth).
p_like = no_icp(pcl, "icp") + pcl["icp_from_truth_ms"]
print(f"speed-up cairn vs PCL, without segmentation, PCL's ICP started at the truth: {p_like / c_reg:.1f}x")
if o3d:
    print(f"speed-up cairn vs Open3D, without segmentation (cairn w/o merge): {o_reg / c_reg:.1f}x")
print()
line("result", [c for c, _ in cols])
for key, label, f in [("success", "success (own test)", "{:.0f}"), ("correct", "within 2 deg / 10 cm", "{:.0f}"),
                      ("rotation_deg", "rotation error [deg]", "{:.3f}"),
                      ("translation_m", "translation error [mm]", "{:.1f}"),
                      ("object_points", "object-segment points", "{:.0f}"),
                      ("keypoints", "keypoints", "{:.0f}"),
                      ("correspondences", "correspondences", "{:.0f}"),
                      ("matched_segments", "matched segments", "{:.0f}")]:
    vals = []
    for name, b in cols:
        v = b.get(key) if b else None
        if v is None and name in ("PCL", "Open3D") and key == "object_points": v = b.get("points") if b else None
        if v is not None and key == "translation_m": v *= 1000
        vals.append("" if v is None else f.format(v))
    line(label, vals)
print("  (PCL and Open3D have no acceptance test of their own: their success is 'within 2 deg / 10 cm')")
print()
for name, b in cols[:2]:
    if b and "accepted_from_centroids" in b:
        print(f"{name}: accepted alignment from {'centroid-pair hypotheses' if b['accepted_from_centroids'] else 'a consistency group'}"
              f" ({b['candidates']:.0f} consistency groups, {b['matched_segments']:.0f} matched segments)")
g = lambda key: pcl.get(key, float("nan"))  # older result files lack some diagnostics
print(f"PCL: {g('clusters'):.0f} consistency groups ({g('failed_refits'):.0f} whose RANSAC refit failed, left out), "
      f"best-verified has {g('best_cluster'):.0f} correspondences and {g('matched_segments'):.0f} matched segments; "
      f"{g('clusters_near_truth'):.0f} groups within 10 deg / 1 m of the truth, {g('clusters_near_truth_in_b'):.0f} of "
      f"them among the b most-voted; ICP {g('icp_iterations'):.0f} iterations (from the truth, on the segments matched "
      f"there: {g('icp_from_truth_iterations'):.0f} iterations, {g('icp_from_truth_ms'):.0f} ms)")
if o3d:
    print(f"Open3D: {o3d['voxelised_points']:.0f} voxelised points, RANSAC fitness {o3d['ransac_fitness']:.3f}, "
          f"{o3d['ransac_inliers']:.0f} inliers")
PY
