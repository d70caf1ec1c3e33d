#include "cairn/core/kdtree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <nanoflann.hpp>
#include <numeric>

namespace cairn {
// Named (not anonymous): KdTree::Impl holds these, and GCC warns (-Wsubobject-linkage) when a
// class with external linkage has members of internal types once the file is in a unity batch.
namespace kdtree_detail {

/// The points nanoflann indexes (all of them, or a compact copy of the finite ones).
struct SpanAdaptor {
  std::span<const Vec3f> pts;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return pts.size(); }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t dim) const { return pts[i][int(dim)]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};

/// Indexed position -> point index: identity, or (some points not finite) through `ids`.
struct IdMap {
  const std::uint32_t* ids = nullptr;
  [[nodiscard]] std::uint32_t operator()(std::uint32_t i) const { return ids ? ids[i] : i; }
};

using Index = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, SpanAdaptor>,
                                                  SpanAdaptor, 3, std::uint32_t>;

/// nanoflann result set that forwards every hit to a callback.
struct CallbackResultSet {
  float radius_sq;
  IdMap id;
  void* ctx;
  void (*visit)(void*, std::uint32_t, float);
  std::size_t count = 0;
  void init() {}
  [[nodiscard]] std::size_t size() const { return count; }
  [[nodiscard]] bool full() const { return true; }
  bool addPoint(float d2, std::uint32_t i) {
    if (d2 < radius_sq) {
      visit(ctx, id(i), d2);
      ++count;
    }
    return true;
  }
  [[nodiscard]] float worstDist() const { return radius_sq; }
};

/// nanoflann result set keeping the nearest hit below a bound (the bound prunes from the start;
/// like nanoflann's k = 1 search, a later hit replaces the kept one only when strictly closer).
struct BoundedNearestResultSet {
  float worst;
  std::uint32_t index = 0;
  bool found = false;
  void init() {}
  [[nodiscard]] std::size_t size() const { return found ? 1 : 0; }
  [[nodiscard]] bool full() const { return true; }
  bool addPoint(float d2, std::uint32_t i) {
    if (d2 < worst) {
      worst = d2;
      index = i;
      found = true;
    }
    return true;
  }
  [[nodiscard]] float worstDist() const { return worst; }
};

}  // namespace kdtree_detail

/// Points with a NaN or infinite coordinate have no distance to anything: when there are such,
/// the tree indexes a compact copy of the finite points (the common all-finite case copies
/// nothing and pays no indirection per distance) and maps what it finds back.
struct KdTree::Impl {
  bool all_finite;
  std::vector<std::uint32_t> ids;  // the finite points' indices, when some are not
  std::vector<Vec3f> compact;      // those points
  kdtree_detail::SpanAdaptor adaptor;
  kdtree_detail::Index index;
  Impl(std::span<const Vec3f> p, int leaf)
      // nanoflann's constructor builds the index (a second buildIndex() would build it twice).
      : all_finite(std::all_of(p.begin(), p.end(), [](const Vec3f& q) { return q.allFinite(); })),
        ids(all_finite ? std::vector<std::uint32_t>{} : finite_ids(p)),
        compact(gather(p, ids)),
        adaptor{all_finite ? p : std::span<const Vec3f>(compact)},
        index(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(std::size_t(leaf))) {}
  [[nodiscard]] kdtree_detail::IdMap id() const { return {all_finite ? nullptr : ids.data()}; }
  [[nodiscard]] std::size_t count() const { return adaptor.pts.size(); }

  static std::vector<std::uint32_t> finite_ids(std::span<const Vec3f> p) {
    std::vector<std::uint32_t> ids;
    for (std::size_t i = 0; i < p.size(); ++i)
      if (p[i].allFinite()) ids.push_back(std::uint32_t(i));
    return ids;
  }
  static std::vector<Vec3f> gather(std::span<const Vec3f> p, const std::vector<std::uint32_t>& ids) {
    std::vector<Vec3f> c;
    c.reserve(ids.size());
    for (std::uint32_t i : ids) c.push_back(p[i]);
    return c;
  }
};

KdTree::KdTree(std::span<const Vec3f> points, int leaf_size)
    : points_(points), impl_(std::make_unique<Impl>(points, leaf_size)) {}
KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

void KdTree::knn(const Vec3f& query, std::size_t k, Neighbors& out) const {
  k = query.allFinite() ? std::min(k, impl_->count()) : 0;  // no distance to a NaN query
  out.indices.resize(k);
  out.sq_dists.resize(k);
  if (k == 0) return;
  const auto found = impl_->index.knnSearch(query.data(), k, out.indices.data(), out.sq_dists.data());
  out.indices.resize(found);
  out.sq_dists.resize(found);
  if (!impl_->all_finite)
    for (auto& i : out.indices) i = impl_->id()(i);
}

void KdTree::radius_visit(const Vec3f& query, float radius, void* ctx,
                          void (*visit)(void*, std::uint32_t, float)) const {
  if (impl_->count() == 0 || !query.allFinite()) return;
  kdtree_detail::CallbackResultSet rs{radius * radius, impl_->id(), ctx, visit};
  impl_->index.findNeighbors(rs, query.data(), nanoflann::SearchParams(0, 0.0f, false));
}

void KdTree::radius(const Vec3f& query, float radius, Neighbors& out, bool sorted) const {
  out.clear();
  for_each_in_radius(query, radius, [&](std::uint32_t i, float d2) {
    out.indices.push_back(i);
    out.sq_dists.push_back(d2);
  });
  if (!sorted || out.size() < 2) return;
  std::vector<std::uint32_t> order(out.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(),
            [&](auto a, auto b) { return out.sq_dists[a] < out.sq_dists[b]; });
  Neighbors s;
  for (auto o : order) {
    s.indices.push_back(out.indices[o]);
    s.sq_dists.push_back(out.sq_dists[o]);
  }
  out = std::move(s);
}

std::uint32_t KdTree::nearest(const Vec3f& query, float* sq_dist) const {
  std::uint32_t idx = 0;
  float d2 = std::numeric_limits<float>::infinity();  // no finite point, or a NaN query: none near
  if (impl_->count() > 0 && query.allFinite()) {
    impl_->index.knnSearch(query.data(), 1, &idx, &d2);
    idx = impl_->id()(idx);
  }
  if (sq_dist) *sq_dist = d2;
  return idx;
}

std::uint32_t KdTree::nearest_within(const Vec3f& query, float max_sq_dist, float* sq_dist) const {
  float d2 = std::numeric_limits<float>::infinity();
  std::uint32_t idx = 0;
  if (impl_->count() > 0 && query.allFinite() && max_sq_dist >= 0.0f) {
    // The search prunes with a slightly larger bound: nanoflann's lower bound of a cell's distance
    // is accumulated in float and may exceed the true distance of a point on the cell's face by a
    // few ulps; the answer is then kept only within max_sq_dist itself.
    constexpr float kRelativeSlack = 1e-4f, kAbsoluteSlack = 1e-10f;  // [m²]: far below any distance test
    kdtree_detail::BoundedNearestResultSet rs{max_sq_dist * (1.0f + kRelativeSlack) + kAbsoluteSlack};
    impl_->index.findNeighbors(rs, query.data(), nanoflann::SearchParams(0, 0.0f, false));
    if (rs.found && rs.worst <= max_sq_dist) {
      d2 = rs.worst;
      idx = impl_->id()(rs.index);
    }
  }
  if (sq_dist) *sq_dist = d2;
  return idx;
}

}  // namespace cairn
