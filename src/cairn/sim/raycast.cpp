#include "cairn/sim/raycast.hpp"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <string>
#include <vector>

#include "cairn/core/error.hpp"

namespace cairn::sim {

struct RayScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<std::int32_t> labels;  // per Embree geometry id
  std::size_t triangles = 0;
  bool committed = false;

  Impl() {
    device = rtcNewDevice(nullptr);
    if (device == nullptr) throw InputError("Embree: could not create a device");
    scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  }
  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
};

RayScene::RayScene() : impl_(std::make_unique<Impl>()) {}
RayScene::~RayScene() = default;
RayScene::RayScene(RayScene&&) noexcept = default;
RayScene& RayScene::operator=(RayScene&&) noexcept = default;

void RayScene::add_mesh(const io::Mesh& mesh, std::int32_t label) {
  if (impl_->committed) throw InputError("RayScene::add_mesh: the scene is already committed");
  const auto& pts = mesh.vertices.points;
  if (pts.empty() || mesh.triangles.empty()) throw InputError("RayScene::add_mesh: empty mesh");
  const std::size_t nv = pts.size();
  for (const auto& f : mesh.triangles) {
    if (f[0] >= nv || f[1] >= nv || f[2] >= nv) {
      throw InputError("RayScene::add_mesh: triangle index out of range");
    }
  }
  RTCGeometry geom = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                         3 * sizeof(float), nv));
  for (std::size_t i = 0; i < nv; ++i) {
    const Eigen::Vector3d p = pts[i].cast<double>() + mesh.vertices.origin;
    vb[3 * i + 0] = static_cast<float>(p.x());
    vb[3 * i + 1] = static_cast<float>(p.y());
    vb[3 * i + 2] = static_cast<float>(p.z());
  }
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                            3 * sizeof(unsigned), mesh.triangles.size()));
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) ib[3 * i + k] = static_cast<unsigned>(mesh.triangles[i][k]);
  }
  rtcCommitGeometry(geom);
  const unsigned id = rtcAttachGeometry(impl_->scene, geom);
  rtcReleaseGeometry(geom);
  if (impl_->labels.size() <= id) impl_->labels.resize(id + 1, RayHit::kNoLabel);
  impl_->labels[id] = label;
  impl_->triangles += mesh.triangles.size();
}

void RayScene::commit() {
  if (impl_->committed) return;
  rtcCommitScene(impl_->scene);
  impl_->committed = true;
}

bool RayScene::committed() const { return impl_->committed; }
std::size_t RayScene::num_triangles() const { return impl_->triangles; }

namespace {
void fill_ray(const Ray& r, RTCRay& out) {
  out.org_x = r.origin.x();
  out.org_y = r.origin.y();
  out.org_z = r.origin.z();
  out.dir_x = r.direction.x();
  out.dir_y = r.direction.y();
  out.dir_z = r.direction.z();
  out.tnear = r.t_near;
  out.tfar = r.t_far;
  out.time = 0.0f;
  out.mask = 0xFFFFFFFFu;
  out.id = 0;
  out.flags = 0;
}
}  // namespace

RayHit RayScene::intersect(const Ray& ray) const {
  if (!impl_->committed) throw InputError("RayScene::intersect: commit() the scene first");
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit rh;
  fill_ray(ray, rh.ray);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &rh);
  RayHit hit;
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
  hit.t = rh.ray.tfar;
  hit.label = impl_->labels[rh.hit.geomID];
  Eigen::Vector3f n(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
  const float len = n.norm();
  if (len > 0.0f) n /= len;
  if (n.dot(ray.direction) > 0.0f) n = -n;
  hit.normal = n;
  return hit;
}

void RayScene::intersect(std::span<const Ray> rays, std::span<RayHit> hits) const {
  if (rays.size() != hits.size()) throw InputError("RayScene::intersect: rays and hits differ in size");
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays.size(), 1024),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t i = r.begin(); i != r.end(); ++i) hits[i] = intersect(rays[i]);
                    });
}

bool RayScene::occluded(const Ray& ray) const {
  if (!impl_->committed) throw InputError("RayScene::occluded: commit() the scene first");
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRay r;
  fill_ray(ray, r);
  rtcOccluded1(impl_->scene, &context, &r);
  return r.tfar < 0.0f;  // Embree sets tfar to -inf on a hit
}

}  // namespace cairn::sim
