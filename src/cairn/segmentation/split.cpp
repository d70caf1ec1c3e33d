#include "cairn/segmentation/split.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <queue>
#include <set>
#include <tuple>

#include <Eigen/Eigenvalues>

#include "cairn/core/error.hpp"
#include "cairn/core/cell_map.hpp"

namespace cairn {
namespace {

constexpr float kEmpty = -std::numeric_limits<float>::infinity();

void validate(const SplitConfig& c) {
  if (!(c.voxel_size > 0) || !std::isfinite(c.voxel_size)) throw ConfigError("segmentation.split.voxel_size must be > 0");
  if (!(c.min_seam_depth >= 0) || !std::isfinite(c.min_seam_depth))
    throw ConfigError("segmentation.split.min_seam_depth must be >= 0");
  if (!(c.min_crease_depth >= 0) || !std::isfinite(c.min_crease_depth))
    throw ConfigError("segmentation.split.min_crease_depth must be >= 0");
  if (!(c.seam_angle_deg >= 0 && c.seam_angle_deg <= 180))
    throw ConfigError("segmentation.split.seam_angle_deg must be within [0, 180]");
  if (!(c.max_rise_deg >= 0 && c.max_rise_deg <= 90))
    throw ConfigError("segmentation.split.max_rise_deg must be within [0, 90]");
  if (c.min_part_points < 0) throw ConfigError("segmentation.split.min_part_points must be >= 0");
  if (!(c.min_part_height >= 0) || !std::isfinite(c.min_part_height))
    throw ConfigError("segmentation.split.min_part_height must be >= 0");
  if (!(c.min_part_area >= 0) || !std::isfinite(c.min_part_area))
    throw ConfigError("segmentation.split.min_part_area must be >= 0");
}

/// The cluster's surface as a graph of occupied voxels (26-neighbourhood), each voxel carrying
/// the highest height above the ground of its points.
struct SurfaceGraph {
  std::vector<float> top;               // per voxel
  std::vector<std::uint32_t> count;     // points per voxel
  std::vector<std::uint32_t> adjacency; // neighbours of voxel v: [begin[v], begin[v+1])
  std::vector<std::uint32_t> begin;
  std::vector<std::uint32_t> voxel_of;  // per cluster point
  std::vector<Eigen::Vector3d> sum;     // per voxel: sum of the points
  std::vector<Eigen::Matrix3d> outer;   // per voxel: sum of p p^T

  template <class F>
  void for_neighbours(std::size_t v, F&& f) const {
    for (auto k = begin[v]; k < begin[v + 1]; ++k) f(adjacency[k]);
  }
};

SurfaceGraph surface_graph(std::span<const Vec3f> points, std::span<const float> height,
                           std::span<const std::uint32_t> indices, float voxel) {
  SurfaceGraph g;
  CellMap map(indices.size());
  std::vector<Eigen::Array3i> coord;  // per voxel, for the adjacency
  const float inv = 1.0f / voxel;
  g.voxel_of.resize(indices.size());
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const Eigen::Array3i c = (points[indices[k]].array() * inv).floor().cast<int>();
    const std::uint32_t v = map.insert(CellMap::key(c.x(), c.y(), c.z()), std::uint32_t(coord.size()));
    if (v == coord.size()) {
      coord.push_back(c);
      g.top.push_back(kEmpty);
      g.count.push_back(0);
      g.sum.emplace_back(Eigen::Vector3d::Zero());
      g.outer.emplace_back(Eigen::Matrix3d::Zero());
    }
    const Eigen::Vector3d p = points[indices[k]].cast<double>();
    g.sum[v] += p;
    g.outer[v] += p * p.transpose();
    g.voxel_of[k] = v;
    g.top[v] = std::max(g.top[v], height[indices[k]]);
    ++g.count[v];
  }
  g.begin.assign(1, 0);
  for (const Eigen::Array3i& c : coord) {
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          if (!(dx || dy || dz)) continue;
          const std::uint32_t n = map.find(CellMap::key(c.x() + dx, c.y() + dy, c.z() + dz));
          if (n != CellMap::kAbsent) g.adjacency.push_back(n);
        }
    g.begin.push_back(std::uint32_t(g.adjacency.size()));
  }
  return g;
}

struct Flooding {
  std::vector<std::uint32_t> parent;  // union-find over voxels (roots: hills)
  std::vector<float> peak;            // per root: the hill's top
  std::vector<Eigen::Vector3d> sum;   // per root: sum of the hill's points
  std::vector<double> count;          // per root: its number of points
  std::vector<double> voxels;         // per root: its number of voxels

  std::uint32_t find(std::uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  }
  void attach(std::uint32_t child, std::uint32_t root) {
    parent[child] = root;
    sum[root] += sum[child];
    count[root] += count[child];
    voxels[root] += voxels[child];
    peak[root] = std::max(peak[root], peak[child]);
  }
};

/// Surface normal of voxel v within hill `root`: PCA over v and its neighbours of the same hill
/// (so the other side of a seam does not blur it), oriented up, or on steep faces outward (in xy)
/// from the hill's centre.
Eigen::Vector3d hill_normal(const SurfaceGraph& h, Flooding& f, std::uint32_t v, std::uint32_t root) {
  constexpr double kSteepNormalZ = 0.5;  // |n_z| below this: a steep face
  Eigen::Vector3d sum = h.sum[v];
  Eigen::Matrix3d outer = h.outer[v];
  double n = h.count[v];
  h.for_neighbours(v, [&](std::uint32_t m) {
    if (f.find(m) != root) return;
    sum += h.sum[m];
    outer += h.outer[m];
    n += h.count[m];
  });
  const Eigen::Vector3d mean = sum / n;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(outer / n - mean * mean.transpose());
  const Eigen::Vector3d normal = es.eigenvectors().col(0);
  const Eigen::Vector3d out = mean - f.sum[root] / f.count[root];
  const bool flip = std::abs(normal.z()) >= kSteepNormalZ ? normal.z() < 0.0 : normal.head<2>().dot(out.head<2>()) < 0.0;
  return flip ? -normal : normal;
}

/// Watershed from the top down with persistence merging (file header): a voxel drains into the
/// hill of its highest processed neighbour whose surface it continues (steepest ascent; it does
/// not continue a surface when it rises in front of that neighbour's tangent plane at more than
/// asin(max_rise) — the far side of a concave crease); where two hills meet, the lower one
/// survives when its top is at least `persistence` above this voxel (the saddle).
Flooding flood(const SurfaceGraph& h, double persistence, double max_rise) {
  const std::size_t n = h.top.size();
  Flooding f{std::vector<std::uint32_t>(n), h.top, h.sum, std::vector<double>(h.count.begin(), h.count.end()),
             std::vector<double>(n, 1.0)};
  std::iota(f.parent.begin(), f.parent.end(), 0u);
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return h.top[a] != h.top[b] ? h.top[a] > h.top[b] : a < b;
  });
  std::vector<std::uint8_t> done(n, 0), has_normal(n, 0);
  std::vector<Eigen::Vector3d> normal(n);
  std::vector<std::uint32_t> processed, roots;
  const auto centre = [&](std::uint32_t v) -> Eigen::Vector3d { return h.sum[v] / double(h.count[v]); };
  // c lies on m's surface unless it rises in front of m's tangent plane (then it belongs to
  // another body leaning against m's: the far side of a concave crease).
  const auto on_surface_of = [&](std::uint32_t c, std::uint32_t m) {
    if (!has_normal[m]) normal[m] = hill_normal(h, f, m, f.find(m)), has_normal[m] = 1;
    const Eigen::Vector3d d = centre(c) - centre(m);
    return normal[m].dot(d) <= max_rise * d.norm();
  };
  for (const std::uint32_t c : order) {
    processed.clear();
    h.for_neighbours(c, [&](std::uint32_t m) {
      if (done[m]) processed.push_back(m);
    });
    done[c] = 1;
    if (processed.empty()) continue;  // a new hill
    std::sort(processed.begin(), processed.end(), [&](std::uint32_t a, std::uint32_t b) {
      return h.top[a] != h.top[b] ? h.top[a] > h.top[b] : a < b;
    });
    // c drains into the hill of its highest neighbour whose surface it continues (steepest ascent)
    const auto it = std::find_if(processed.begin(), processed.end(), [&](std::uint32_t m) { return on_surface_of(c, m); });
    f.attach(c, f.find(it != processed.end() ? *it : processed.front()));
    roots.clear();
    for (const std::uint32_t m : processed) roots.push_back(f.find(m));
    for (const std::uint32_t r : roots) {
      const std::uint32_t a = f.find(c), b = f.find(r);
      if (a == b) continue;
      if (double(std::min(f.peak[a], f.peak[b]) - h.top[c]) < persistence) {
        const bool a_higher = f.peak[a] != f.peak[b] ? f.peak[a] > f.peak[b] : a < b;
        f.attach(a_higher ? b : a, a_higher ? a : b);  // a bump: the lower hill joins the higher
      }
    }
  }
  return f;
}

/// The fine hills: every dip of at least min_crease_depth (the smallest that may separate two
/// stones) keeps its hills apart; merge_hills then decides which are one stone.
Flooding fine_hills(const SurfaceGraph& h, const SplitConfig& c) {
  return flood(h, std::min(c.min_crease_depth, c.min_seam_depth), std::sin(c.max_rise_deg * M_PI / 180.0));
}

/// What two hills share: the highest saddle, and their contact edges (adjacent voxels of the two),
/// how many of them a sharp concave crease.
struct Contact {
  float saddle = kEmpty;
  std::size_t edges = 0, creased = 0;
};

/// How far the lower of two hills' tops rises above their saddle [m].
double saddle_depth(const Flooding& f, std::uint32_t a, std::uint32_t b, const Contact& c) {
  return double(std::min(f.peak[a], f.peak[b]) - c.saddle);
}

/// The cluster's points grouped by the hill (root) their voxel belongs to, hills in order of
/// their first point.
struct HillPoints {
  std::map<std::uint32_t, std::size_t> index;      // hill root -> group
  std::vector<std::vector<std::uint32_t>> points;  // indices into the cloud, ascending
};
HillPoints group_by_hill(const SurfaceGraph& h, Flooding& f, std::span<const std::uint32_t> indices) {
  HillPoints g;
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const auto [it, inserted] = g.index.emplace(f.find(h.voxel_of[k]), g.points.size());
    if (inserted) g.points.emplace_back();
    g.points[it->second].push_back(indices[k]);
  }
  return g;
}

/// Per pair of hills (roots, ascending) the contact along all their adjacent voxels. An edge
/// (a, b) is creased when the normals of the two sides turn towards each other (LCCP's
/// convexity criterion, Stein et al. 2014: (n_a - n_b)·(x_a - x_b) < 0) by at least the angle.
std::map<std::pair<std::uint32_t, std::uint32_t>, Contact> contacts(const SurfaceGraph& h, Flooding& f,
                                                                    double angle_deg) {
  const double cos_angle = std::cos(angle_deg * M_PI / 180.0);
  std::map<std::pair<std::uint32_t, std::uint32_t>, Contact> out;
  std::vector<Eigen::Vector3d> normal(h.top.size());
  std::vector<std::uint8_t> has_normal(h.top.size(), 0);
  const auto normal_of = [&](std::uint32_t v) -> const Eigen::Vector3d& {
    if (!has_normal[v]) normal[v] = hill_normal(h, f, v, f.find(v)), has_normal[v] = 1;
    return normal[v];
  };
  for (std::uint32_t a = 0; a < h.top.size(); ++a)
    h.for_neighbours(a, [&](std::uint32_t b) {
      const std::uint32_t ra = f.find(a), rb = f.find(b);
      if (b < a || ra == rb) return;
      Contact& c = out[std::minmax(ra, rb)];
      c.saddle = std::max(c.saddle, std::min(h.top[a], h.top[b]));
      ++c.edges;
      const Eigen::Vector3d& na = normal_of(a);
      const Eigen::Vector3d& nb = normal_of(b);
      const Eigen::Vector3d d = h.sum[a] / double(h.count[a]) - h.sum[b] / double(h.count[b]);
      c.creased += na.dot(nb) <= cos_angle && (na - nb).dot(d) < 0.0;
    });
  return out;
}

/// The hills as a region adjacency graph, kept up to date as they merge: per hill its contacts
/// with the others (a merge moves the absorbed hill's contacts to the survivor).
class HillGraph {
 public:
  HillGraph(Flooding& f, const std::map<std::pair<std::uint32_t, std::uint32_t>, Contact>& fine, std::size_t voxels)
      : f_(f) {
    for (std::uint32_t v = 0; v < voxels; ++v) roots_.insert(f.find(v));
    for (const auto& [ab, c] : fine) {
      adjacency_[ab.first][ab.second] = c;
      adjacency_[ab.second][ab.first] = c;
    }
  }
  [[nodiscard]] const std::set<std::uint32_t>& roots() const { return roots_; }
  [[nodiscard]] const std::map<std::uint32_t, Contact>& contacts(std::uint32_t root) { return adjacency_[root]; }
  [[nodiscard]] double depth(std::uint32_t a, std::uint32_t b, const Contact& c) const {
    return saddle_depth(f_, a, b, c);
  }

  void merge(std::uint32_t from, std::uint32_t into) {
    f_.attach(from, into);
    roots_.erase(from);
    auto absorbed = std::move(adjacency_[from]);
    adjacency_.erase(from);
    auto& survivor = adjacency_[into];
    survivor.erase(from);
    for (const auto& [x, c] : absorbed) {
      if (x == into) continue;
      auto& other = adjacency_[x];
      other.erase(from);
      add(survivor[x], c);
      add(other[into], c);
    }
  }

 private:
  static void add(Contact& to, const Contact& c) {
    to.saddle = std::max(to.saddle, c.saddle);
    to.edges += c.edges;
    to.creased += c.creased;
  }
  Flooding& f_;
  std::set<std::uint32_t> roots_;
  std::map<std::uint32_t, std::map<std::uint32_t, Contact>> adjacency_;
};

/// Merges the hills of the fine flooding into stones: two hills are one stone unless the lower
/// top rises min_seam_depth above their saddle, or min_crease_depth above it while at least
/// min_crease_share of their contact is a sharp concave crease. Shallowest pair first (a queue
/// whose stale entries are re-checked when they come up); the remaining pairs are the seams.
void merge_hills(Flooding& f, HillGraph& g, const SplitConfig& config) {
  const auto same_stone = [&](std::uint32_t a, std::uint32_t b, const Contact& c) {
    const double depth = g.depth(a, b, c);
    const bool crease = double(c.creased) >= config.min_crease_share * double(c.edges);
    return !(depth >= config.min_seam_depth || (crease && depth >= config.min_crease_depth));
  };
  using Entry = std::tuple<double, std::uint32_t, std::uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue;
  const auto push_contacts = [&](std::uint32_t a) {
    for (const auto& [b, c] : g.contacts(a))
      if (same_stone(a, b, c)) queue.emplace(g.depth(a, b, c), std::min(a, b), std::max(a, b));
  };
  for (const std::uint32_t r : g.roots()) push_contacts(r);
  while (!queue.empty()) {
    const auto [queued, a, b] = queue.top();
    queue.pop();
    if (f.find(a) != a || f.find(b) != b) continue;  // one of them merged since
    const auto& contacts = g.contacts(a);
    const auto it = contacts.find(b);
    if (it == contacts.end() || !same_stone(a, b, it->second)) continue;
    if (const double now = g.depth(a, b, it->second); now > queued) {  // grew since: wait its turn
      queue.emplace(now, a, b);
      continue;
    }
    const bool a_higher = f.peak[a] != f.peak[b] ? f.peak[a] > f.peak[b] : a < b;
    g.merge(a_higher ? b : a, a_higher ? a : b);
    push_contacts(a_higher ? a : b);
  }
}

/// Merges hills that are too small, or too low, to be a stone into the neighbour they share the
/// highest saddle with (the largest hill when they touch none), smallest first.
void merge_small_parts(Flooding& f, HillGraph& g, const SplitConfig& c) {
  const double voxel_area = c.voxel_size * c.voxel_size;
  const auto small = [&](std::uint32_t r) {
    return f.count[r] < double(c.min_part_points) || f.voxels[r] * voxel_area < c.min_part_area ||
           double(f.peak[r]) < c.min_part_height;
  };
  std::set<std::pair<double, std::uint32_t>> queue;  // (points, hill)
  for (const std::uint32_t r : g.roots())
    if (small(r)) queue.emplace(f.count[r], r);
  while (!queue.empty() && g.roots().size() > 1) {
    const std::uint32_t victim = queue.begin()->second;
    queue.erase(queue.begin());
    if (f.find(victim) != victim || !small(victim)) continue;
    std::uint32_t into = victim;
    float best = kEmpty;
    for (const auto& [x, contact] : g.contacts(victim))
      if (into == victim || contact.saddle > best) best = contact.saddle, into = x;
    if (into == victim)  // touches no other hill
      for (const std::uint32_t r : g.roots())
        if (r != victim && (into == victim || f.count[r] > f.count[into])) into = r;
    g.merge(victim, into);
    if (small(into)) queue.emplace(f.count[into], into);
  }
}

}  // namespace

HillContacts hill_contacts(std::span<const Vec3f> points, std::span<const float> height,
                           std::span<const std::uint32_t> indices, const SplitConfig& config) {
  validate(config);
  HillContacts out;
  if (indices.empty()) return out;
  const SurfaceGraph h = surface_graph(points, height, indices, float(config.voxel_size));
  Flooding f = fine_hills(h, config);
  HillPoints hills = group_by_hill(h, f, indices);
  for (const auto& [ab, c] : contacts(h, f, config.seam_angle_deg)) {
    const auto a = hills.index.find(ab.first), b = hills.index.find(ab.second);
    if (a == hills.index.end() || b == hills.index.end()) continue;
    out.contacts.push_back({a->second, b->second, saddle_depth(f, ab.first, ab.second, c),
                            double(c.creased) / double(c.edges), c.edges});
  }
  out.hills = std::move(hills.points);
  return out;
}

std::vector<ClusterPart> split_cluster(std::span<const Vec3f> points, std::span<const float> height,
                                       std::span<const std::uint32_t> indices, const SplitConfig& config) {
  validate(config);
  const auto whole = [&] { return std::vector<ClusterPart>{{{indices.begin(), indices.end()}, 0.0}}; };
  if (!config.enabled || indices.empty()) return whole();
  const SurfaceGraph h = surface_graph(points, height, indices, float(config.voxel_size));
  Flooding f = fine_hills(h, config);
  HillGraph g(f, contacts(h, f, config.seam_angle_deg), h.top.size());
  merge_hills(f, g, config);
  merge_small_parts(f, g, config);

  HillPoints hills = group_by_hill(h, f, indices);
  if (hills.points.size() == 1) return whole();
  std::vector<ClusterPart> parts(hills.points.size());
  for (std::size_t p = 0; p < parts.size(); ++p) parts[p].indices = std::move(hills.points[p]);
  for (const auto& [root, p] : hills.index) {
    double shallowest = std::numeric_limits<double>::infinity();
    for (const auto& [x, c] : g.contacts(root)) shallowest = std::min(shallowest, g.depth(root, x, c));
    parts[p].seam_depth = std::isfinite(shallowest) ? shallowest : 0.0;
  }
  std::stable_sort(parts.begin(), parts.end(),
                   [](const ClusterPart& a, const ClusterPart& b) { return a.indices.size() > b.indices.size(); });
  return parts;
}

}  // namespace cairn
