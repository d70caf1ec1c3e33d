// Drone pre-map (Sec. 4.1): flight plan, ray-cast multi-view reconstruction, SfM and VINS frames.
#include "cairn/sim/drone.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>

#include "cairn/core/cell_map.hpp"
#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"

namespace cairn::sim {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;
constexpr int kMaxImageSide = 20000;         // [px]
constexpr std::size_t kMaxImages = 100000;   // flight plan guard
constexpr double kMaxCells = 1e6;            // |cell index| per axis (CellMap packs ±2^20)
constexpr float kSurfaceOffset = 0.002f;     // [m] occlusion rays start this far off the surface
constexpr double kVinsZTranslation = 1.0;    // [m] VINS frame z offset range (±)
constexpr double kDriftTurn = 0.3;           // VINS drift direction random walk [1/sqrt(m)]
constexpr double kPixelNoise = 0.3;          // [px] COLMAP observation noise (reprojection error)
constexpr double kColorCell = 0.4;           // [m] terrain colour variation scale
constexpr double kColorJitter = 10.0;        // per-point colour noise (0..255 scale, ±)
// Fusion cell edge per target spacing: one point per cube of edge e has a mean nearest-neighbour
// distance of about 0.67 e on surfaces (measured), so e = 1.5 × point_spacing.
constexpr double kCellPerSpacing = 1.5;

// Independent random streams, so that e.g. the point count does not change the frames.
enum Stream : std::uint64_t { kFrames = 1, kSfmResiduals = 2, kVins = 3, kPoints = 4, kColmap = 5 };

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}
std::mt19937_64 stream(std::uint64_t seed, Stream s) { return std::mt19937_64(splitmix64(seed ^ splitmix64(s))); }

Vector3d normal3(std::mt19937_64& rng) {
  const double x = standard_normal(rng), y = standard_normal(rng);
  return {x, y, standard_normal(rng)};
}

/// Rotation exp([w]x) for a small rotation vector w.
Matrix3d exp_so3(const Vector3d& w) {
  const double a = w.norm();
  if (a < 1e-15) return Matrix3d::Identity();
  return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

void require(bool ok, const std::string& what) {
  if (!ok) throw ConfigError("drone: " + what);
}

void validate(const DroneConfig& c) {
  require(c.altitude > 0 && std::isfinite(c.altitude), "altitude must be positive");
  require(std::isfinite(c.center_x) && std::isfinite(c.center_y), "center must be finite");
  require(c.extent_x > 0 && c.extent_y > 0 && std::isfinite(c.extent_x * c.extent_y), "extent must be positive");
  require(c.forward_overlap >= 0 && c.forward_overlap <= 0.99, "forward_overlap must be in [0, 0.99]");
  require(c.side_overlap >= 0 && c.side_overlap <= 0.99, "side_overlap must be in [0, 0.99]");
  require(c.orbit_images >= 0, "orbit_images must be >= 0");
  require(c.lawnmower || c.orbit_images > 0, "no images: enable lawnmower or set orbit_images > 0");
  require(c.orbit_radius >= 0 && std::isfinite(c.orbit_radius), "orbit_radius must be >= 0");
  require(c.speed > 0 && std::isfinite(c.speed), "speed must be positive");
  const auto& k = c.camera;
  require(k.width > 0 && k.height > 0 && k.width <= kMaxImageSide && k.height <= kMaxImageSide,
          "camera width/height must be in 1.." + std::to_string(kMaxImageSide));
  require(k.fx > 0 && k.fy > 0 && std::isfinite(k.fx * k.fy), "camera fx, fy must be positive");
  require(std::isfinite(k.cx) && std::isfinite(k.cy), "camera cx, cy must be finite");
  require(c.pixel_stride >= 1, "pixel_stride must be >= 1");
  require(c.point_spacing >= 1e-3 && std::isfinite(c.point_spacing), "point_spacing must be >= 0.001 m");
  require(c.min_views >= 1, "min_views must be >= 1");
  require(c.max_incidence > 0 && c.max_incidence <= kPi / 2, "max_incidence must be in (0, pi/2]");
  require(c.depth_noise >= 0 && std::isfinite(c.depth_noise), "depth_noise must be >= 0");
  require(c.noise_range > 0 && std::isfinite(c.noise_range), "noise_range must be positive");
  require(c.margin >= 0 && std::isfinite(c.margin), "margin must be >= 0");
  require(c.sfm_min_scale > 0 && c.sfm_min_scale <= c.sfm_max_scale && std::isfinite(c.sfm_max_scale),
          "need 0 < sfm_min_scale <= sfm_max_scale");
  require(c.sfm_max_translation >= 0 && std::isfinite(c.sfm_max_translation), "sfm_max_translation must be >= 0");
  require(c.vins_max_translation >= 0 && std::isfinite(c.vins_max_translation), "vins_max_translation must be >= 0");
  for (double v : {c.sfm_position_noise, c.sfm_rotation_noise, c.vins_position_noise, c.vins_drift,
                   c.vins_rotation_noise})
    require(v >= 0 && std::isfinite(v), "noise and drift values must be >= 0");
  const double cells = (std::max(c.extent_x, c.extent_y) / 2 + c.margin +
                        std::max(std::abs(c.center_x), std::abs(c.center_y)) + c.altitude) /
                       (kCellPerSpacing * c.point_spacing);
  require(cells < kMaxCells, "region too large for point_spacing");
}

// ---- flight plan

struct Shot {
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
};

/// Camera looking along `forward` with image-right along `right` (both unit, orthogonal).
Eigen::Isometry3d camera_pose(const Vector3d& position, const Vector3d& right, const Vector3d& forward) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = right;
  T.linear().col(1) = forward.cross(right);  // image down
  T.linear().col(2) = forward;
  T.translation() = position;
  return T;
}

std::vector<Eigen::Isometry3d> flight_plan(const Site& site, const DroneConfig& c) {
  const double ground = site.terrain.height(c.center_x, c.center_y);
  const double z = ground + c.altitude;
  std::vector<Eigen::Isometry3d> poses;
  if (c.lawnmower) {
    // Nadir camera, image x across the track: footprint across = altitude·width/fx.
    const double across = c.altitude * c.camera.width / c.camera.fx;
    const double along = c.altitude * c.camera.height / c.camera.fy;
    const double line_step = std::max((1.0 - c.side_overlap) * across, 1e-3);
    const double shot_step = std::max((1.0 - c.forward_overlap) * along, 1e-3);
    const double lines_f = std::ceil(c.extent_y / line_step) + 1.0;
    const double shots_f = std::ceil(c.extent_x / shot_step) + 1.0;
    require(lines_f * shots_f < static_cast<double>(kMaxImages), "flight plan has too many images");
    const int lines = static_cast<int>(lines_f), shots = static_cast<int>(shots_f);
    for (int l = 0; l < lines; ++l) {
      const double y = c.center_y - c.extent_y / 2 + c.extent_y * l / std::max(lines - 1, 1);
      const bool forward = l % 2 == 0;  // serpentine: +x, then -x, ...
      const Vector3d right = forward ? Vector3d(0, -1, 0) : Vector3d(0, 1, 0);
      for (int s = 0; s < shots; ++s) {
        const int i = forward ? s : shots - 1 - s;
        const double x = c.center_x - c.extent_x / 2 + c.extent_x * i / std::max(shots - 1, 1);
        poses.push_back(camera_pose({x, y, z}, right, Vector3d(0, 0, -1)));
      }
    }
  }
  require(poses.size() + static_cast<std::size_t>(c.orbit_images) < kMaxImages, "flight plan has too many images");
  const Vector3d target(c.center_x, c.center_y, ground);
  for (int k = 0; k < c.orbit_images; ++k) {
    const double a = 2.0 * kPi * k / c.orbit_images;
    const Vector3d p(c.center_x + c.orbit_radius * std::cos(a), c.center_y + c.orbit_radius * std::sin(a), z);
    const Vector3d forward = (target - p).normalized();
    Vector3d right = forward.cross(Vector3d::UnitZ());
    if (right.norm() < 1e-9) right = Vector3d(std::sin(a), -std::cos(a), 0);  // straight down
    poses.push_back(camera_pose(p, right.normalized(), forward));
  }
  return poses;
}

// ---- reconstruction

struct Sample {
  Eigen::Vector3f p;        // true surface point (world)
  Eigen::Vector3f n;        // unit normal facing the camera that kept it
  std::int32_t label;
  std::uint32_t camera;     // image that kept it
  std::uint64_t key;        // fusion cell
};

/// Camera data for projections, in float for speed.
struct CameraView {
  Eigen::Matrix3f R_cam_world;
  Eigen::Vector3f center;
};

std::vector<Sample> cast_images(const RayScene& scene, const std::vector<CameraView>& views, const DroneConfig& c) {
  const auto& k = c.camera;
  const int nu = (k.width + c.pixel_stride - 1) / c.pixel_stride;
  const int nv = (k.height + c.pixel_stride - 1) / c.pixel_stride;
  const auto n_rays = static_cast<std::size_t>(nu) * static_cast<std::size_t>(nv);
  const double half_x = c.extent_x / 2 + c.margin, half_y = c.extent_y / 2 + c.margin;
  const float cos_max = static_cast<float>(std::cos(c.max_incidence));
  const double inv_cell = 1.0 / (kCellPerSpacing * c.point_spacing);
  const double area = (2 * half_x) * (2 * half_y);
  CellMap cells(static_cast<std::size_t>(2.0 * area * inv_cell * inv_cell) + 1024);

  std::vector<Sample> samples;
  std::vector<Ray> rays(n_rays);
  std::vector<RayHit> hits(n_rays);
  for (std::uint32_t cam = 0; cam < views.size(); ++cam) {
    const Eigen::Matrix3f R_world_cam = views[cam].R_cam_world.transpose();
    const Eigen::Vector3f C = views[cam].center;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_rays, 4096), [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) {
        const double u = static_cast<double>((i % nu) * c.pixel_stride) + 0.5;
        const double v = static_cast<double>((i / nu) * c.pixel_stride) + 0.5;
        const Eigen::Vector3f d((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
        rays[i] = Ray{C, (R_world_cam * d).normalized()};
      }
    });
    scene.intersect(rays, hits);
    for (std::size_t i = 0; i < n_rays; ++i) {  // sequential: the first camera keeps a cell
      const RayHit& h = hits[i];
      if (!h.hit() || -rays[i].direction.dot(h.normal) < cos_max) continue;
      const Eigen::Vector3f p = C + h.t * rays[i].direction;
      if (std::abs(p.x() - c.center_x) > half_x || std::abs(p.y() - c.center_y) > half_y) continue;
      const std::uint64_t key = CellMap::key(static_cast<std::int64_t>(std::floor(p.x() * inv_cell)),
                                             static_cast<std::int64_t>(std::floor(p.y() * inv_cell)),
                                             static_cast<std::int64_t>(std::floor(p.z() * inv_cell)));
      const auto index = static_cast<std::uint32_t>(samples.size());
      if (cells.insert(key, index) == index) samples.push_back({p, h.normal, h.label, cam, key});
    }
  }
  return samples;
}

/// Whether camera j sees the surface point s: in front, inside the image, not at grazing
/// incidence, line of sight free.
bool sees(const RayScene& scene, const CameraView& view, const PinholeCamera& k, float cos_max, const Sample& s) {
  const Eigen::Vector3f to_cam = view.center - s.p;
  const float dist = to_cam.norm();
  if (s.n.dot(to_cam) < cos_max * dist) return false;
  const Eigen::Vector3f x = view.R_cam_world * (s.p - view.center);
  if (x.z() <= 0.0f) return false;
  const double u = k.fx * x.x() / x.z() + k.cx, v = k.fy * x.y() / x.z() + k.cy;
  if (!(u >= 0.0 && u < k.width && v >= 0.0 && v < k.height)) return false;
  const Eigen::Vector3f origin = s.p + kSurfaceOffset * s.n;
  return !scene.occluded(Ray{origin, view.center - origin, 0.0f, 1.0f});
}

/// Per sample: a second image that sees it, or -1 when fewer than min_views images do.
std::vector<std::int64_t> multi_view_check(const RayScene& scene, const std::vector<CameraView>& views,
                                           const std::vector<Sample>& samples, const DroneConfig& c) {
  const float cos_max = static_cast<float>(std::cos(c.max_incidence));
  const auto n_views = static_cast<std::int64_t>(views.size());
  std::vector<std::int64_t> second(samples.size(), -1);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples.size(), 512), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) {
      const Sample& s = samples[i];
      int count = 1;  // the image that kept it
      if (count >= c.min_views) second[i] = s.camera;
      // Neighbours in flight order first: they are the likeliest to see the point too.
      for (std::int64_t step = 1; step < n_views && count < c.min_views; ++step) {
        for (const std::int64_t j : {std::int64_t(s.camera) + step, std::int64_t(s.camera) - step}) {
          if (j < 0 || j >= n_views || count >= c.min_views) continue;
          if (!sees(scene, views[static_cast<std::size_t>(j)], c.camera, cos_max, s)) continue;
          if (++count == 2) second[i] = j;
        }
      }
      if (count < c.min_views) second[i] = -1;
    }
  });
  return second;
}

// ---- colours

double lattice_value(std::int64_t x, std::int64_t y, std::uint64_t seed) {
  const std::uint64_t h = splitmix64(seed ^ splitmix64(static_cast<std::uint64_t>(x) * 0x9e3779b1ull +
                                                       static_cast<std::uint64_t>(y)));
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

/// Smooth value noise in [0, 1] (bilinear with smoothstep weights).
double value_noise(double x, double y, std::uint64_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  const auto smooth = [](double t) { return t * t * (3 - 2 * t); };
  const double tx = smooth(x - fx), ty = smooth(y - fy);
  const double a = lattice_value(ix, iy, seed), b = lattice_value(ix + 1, iy, seed);
  const double d = lattice_value(ix, iy + 1, seed), e = lattice_value(ix + 1, iy + 1, seed);
  return (a * (1 - tx) + b * tx) * (1 - ty) + (d * (1 - tx) + e * tx) * ty;
}

Rgb shade(const Sample& s, std::uint64_t seed, std::mt19937_64& rng) {
  static const Vector3d kSun = Vector3d(0.4, 0.3, 0.85).normalized();
  const double light = 0.55 + 0.45 * std::max(0.0, s.n.cast<double>().dot(kSun));
  Vector3d base;
  if (s.label < 0) {  // terrain: patches of brown soil and grey gravel
    const double t = value_noise(s.p.x() / kColorCell, s.p.y() / kColorCell, seed);
    base = (1 - t) * Vector3d(135, 108, 80) + t * Vector3d(122, 118, 110);
  } else {  // stone k: its own grey, slightly mottled
    const double g = 95.0 + 60.0 * lattice_value(s.label, -7, seed);
    const double m = value_noise(s.p.x() / 0.15 + s.p.z() / 0.15, s.p.y() / 0.15, seed + 1);
    base = Vector3d(g + 6, g + 3, g) * (0.85 + 0.3 * m);
  }
  const double jitter = kColorJitter * (2 * uniform01(rng) - 1);
  Rgb out;
  const auto channel = [&](double v) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(v * light + jitter), 0L, 255L));
  };
  out.r = channel(base.x()), out.g = channel(base.y()), out.b = channel(base.z());
  return out;
}

// ---- frames

Similarity random_sfm_frame(const DroneConfig& c, std::mt19937_64& rng) {
  Similarity S;
  const double lo = std::log(c.sfm_min_scale), hi = std::log(c.sfm_max_scale);
  S.scale = std::exp(lo + (hi - lo) * uniform01(rng));
  if (c.sfm_gravity_aligned) {
    S.rotation = Eigen::AngleAxisd(2 * kPi * uniform01(rng), Vector3d::UnitZ()).toRotationMatrix();
  } else {  // uniform on SO(3): normalised 4-D Gaussian quaternion
    Eigen::Quaterniond q;
    do {
      // One draw per statement: a call's argument order is unspecified (GCC: right to left, the order
      // kept so that a seed gives the same result with every compiler and as before).
      const double z = standard_normal(rng), y = standard_normal(rng), x = standard_normal(rng);
      q = Eigen::Quaterniond(standard_normal(rng), x, y, z);
    } while (q.norm() < 1e-6);
    S.rotation = q.normalized().toRotationMatrix();
  }
  for (int a = 0; a < 3; ++a) S.translation[a] = c.sfm_max_translation * (2 * uniform01(rng) - 1);
  return S;
}

Eigen::Isometry3d random_vins_frame(const DroneConfig& c, std::mt19937_64& rng) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(2 * kPi * uniform01(rng) - kPi, Vector3d::UnitZ()).toRotationMatrix();
  // One draw per statement: a call's argument order is unspecified (GCC: right to left, the order
  // kept so that a seed gives the same result with every compiler and as before).
  const double z = uniform01(rng), y = uniform01(rng), x = uniform01(rng);
  T.translation() = Vector3d(c.vins_max_translation * (2 * x - 1), c.vins_max_translation * (2 * y - 1),
                             kVinsZTranslation * (2 * z - 1));
  return T;
}

Eigen::Quaterniond canonical(const Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1.0;
  return q;
}

std::string image_name(std::size_t i) {
  std::string digits = std::to_string(i);
  if (digits.size() < 4) digits.insert(0, 4 - digits.size(), '0');
  return "frame_" + digits + ".png";
}

std::vector<DroneImage> make_images(const std::vector<Eigen::Isometry3d>& poses, const DroneSurvey& survey,
                                    const DroneConfig& c, std::uint64_t seed) {
  auto sfm_rng = stream(seed, kSfmResiduals);
  auto vins_rng = stream(seed, kVins);
  Vector3d drift = Vector3d::Zero();
  Vector3d drift_dir = normal3(vins_rng).normalized();
  double travelled = 0.0;
  std::vector<DroneImage> images(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    DroneImage& im = images[i];
    im.name = image_name(i);
    im.T_world_cam = poses[i];
    const Vector3d C = poses[i].translation();
    const double step = i == 0 ? 0.0 : (C - poses[i - 1].translation()).norm();
    travelled += step;
    im.timestamp = travelled / c.speed;
    // SfM: small residuals on the camera pose, then the similarity.
    const Vector3d C_noisy = C + c.sfm_position_noise * normal3(sfm_rng);
    const Matrix3d R_noisy = poses[i].linear() * exp_so3(c.sfm_rotation_noise * normal3(sfm_rng));
    const Matrix3d R_cam_sfm = (survey.T_sfm_world.rotation * R_noisy).transpose();
    im.q_cam_sfm = canonical(R_cam_sfm);
    im.t_cam_sfm = -(im.q_cam_sfm.toRotationMatrix() * (survey.T_sfm_world * C_noisy));
    im.position_sfm = -(im.q_cam_sfm.toRotationMatrix().transpose() * im.t_cam_sfm);
    // VINS: drift growing with the distance flown, its direction turning slowly, plus noise.
    drift_dir = (drift_dir + kDriftTurn * std::sqrt(step) * normal3(vins_rng)).normalized();
    drift += c.vins_drift * step * drift_dir;
    im.position_vins = survey.T_vins_world * (C + drift + c.vins_position_noise * normal3(vins_rng));
    im.q_vins_cam = canonical(survey.T_vins_world.linear() * poses[i].linear() *
                              exp_so3(c.vins_rotation_noise * normal3(vins_rng)));
    if (i > 0 && im.q_vins_cam.coeffs().dot(images[i - 1].q_vins_cam.coeffs()) < 0)
      im.q_vins_cam.coeffs() *= -1.0;  // a continuous trajectory: no sign flips between frames
  }
  return images;
}

}  // namespace

DroneSurvey simulate_drone(const Site& site, const RayScene& scene, const DroneConfig& config, std::uint64_t seed) {
  const auto start = std::chrono::steady_clock::now();
  validate(config);
  if (!scene.committed()) throw InputError("simulate_drone: the ray scene is not committed");

  DroneSurvey survey;
  survey.seed = seed;
  survey.camera = config.camera;
  auto frame_rng = stream(seed, kFrames);
  survey.T_sfm_world = random_sfm_frame(config, frame_rng);
  survey.T_world_sfm = survey.T_sfm_world.inverse();
  survey.T_vins_world = random_vins_frame(config, frame_rng);

  const auto poses = flight_plan(site, config);
  survey.images = make_images(poses, survey, config, seed);
  std::vector<CameraView> views;
  views.reserve(poses.size());
  for (const auto& T : poses)
    views.push_back({T.linear().transpose().cast<float>(), T.translation().cast<float>()});

  const auto samples = cast_images(scene, views, config);
  const auto second = multi_view_check(scene, views, samples, config);

  // Noise along the viewing ray (sequential: one generator, deterministic), colours, SfM frame.
  auto point_rng = stream(seed, kPoints);
  const std::uint64_t color_seed = splitmix64(seed ^ 0xc0105ull);
  auto& cloud = survey.cloud;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (second[i] < 0) continue;
    const Sample& s = samples[i];
    const Vector3d p = s.p.cast<double>();
    const Vector3d ray = p - views[s.camera].center.cast<double>();
    const double range = ray.norm();
    const double sigma = config.depth_noise * range / config.noise_range;
    const Vector3d noisy = p + sigma * standard_normal(point_rng) * ray / range;
    cloud.points.push_back((survey.T_sfm_world * noisy).cast<float>());
    if (config.colors) cloud.colors.push_back(shade(s, color_seed, point_rng));
    survey.truth.push_back(s.label);
    survey.views.push_back({s.camera, static_cast<std::uint32_t>(second[i])});
  }
  cloud.labels = survey.truth;
  survey.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return survey;
}

io::ColmapModel to_colmap_model(const DroneSurvey& survey, std::size_t max_points) {
  const auto& k = survey.camera;
  io::ColmapModel model;
  model.cameras.push_back({1, "PINHOLE", k.width, k.height, {k.fx, k.fy, k.cx, k.cy}});
  for (std::size_t i = 0; i < survey.images.size(); ++i) {
    const auto& im = survey.images[i];
    io::ColmapImage c;
    c.id = static_cast<std::uint32_t>(i + 1);
    c.q_cam_world = im.q_cam_sfm;
    c.t_cam_world = im.t_cam_sfm;
    c.camera_id = 1;
    c.name = im.name;
    model.images.push_back(std::move(c));
  }
  const std::size_t n = survey.cloud.size();
  if (n == 0 || max_points == 0) return model;
  const std::size_t stride = (n + max_points - 1) / max_points;
  auto rng = stream(survey.seed, kColmap);
  for (std::size_t i = 0; i < n; i += stride) {
    const Vector3d X = survey.cloud.world(i);
    io::ColmapPoint3D p;
    p.id = model.points.size() + 1;
    p.xyz = X;
    if (survey.cloud.has_colors()) p.color = survey.cloud.colors[i];
    double error = 0.0;
    std::vector<std::pair<std::uint32_t, Eigen::Vector2d>> obs;
    for (const std::uint32_t a : survey.views[i]) {
      const auto& im = survey.images[a];
      const Vector3d x = im.q_cam_sfm.toRotationMatrix() * X + im.t_cam_sfm;
      if (x.z() <= 0) continue;
      const double noise_v = standard_normal(rng), noise_u = standard_normal(rng);  // GCC's order (see above)
      const Eigen::Vector2d noise(kPixelNoise * noise_u, kPixelNoise * noise_v);
      const Eigen::Vector2d uv = Eigen::Vector2d(k.fx * x.x() / x.z() + k.cx, k.fy * x.y() / x.z() + k.cy) + noise;
      if (!(uv.x() >= 0 && uv.x() < k.width && uv.y() >= 0 && uv.y() < k.height)) continue;
      obs.emplace_back(a, uv);
      error += noise.norm();
    }
    if (obs.size() < 2 || obs[0].first == obs[1].first) continue;  // a track needs two images
    for (const auto& [a, uv] : obs) {
      auto& pts = model.images[a].points2d;
      p.track.push_back({a + 1, static_cast<std::uint32_t>(pts.size())});
      pts.push_back({uv, static_cast<std::int64_t>(p.id)});
    }
    p.error = error / static_cast<double>(obs.size());
    model.points.push_back(std::move(p));
  }
  return model;
}

std::vector<io::TrajectoryPose> vins_trajectory(const DroneSurvey& survey) {
  std::vector<io::TrajectoryPose> poses;
  poses.reserve(survey.images.size());
  for (const auto& im : survey.images) poses.push_back({im.timestamp, im.position_vins, im.q_vins_cam});
  return poses;
}

void write_drone_survey(const std::filesystem::path& dir, const DroneSurvey& survey) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(dir.string() + ": cannot create directory: " + ec.message());
  io::write_colmap_text(dir / "sparse", to_colmap_model(survey));
  io::write_ply(dir / "drone_cloud.ply", survey.cloud);
  io::write_tum_trajectory(dir / "vins_trajectory.txt", vins_trajectory(survey));

  nlohmann::json truth;
  truth["seed"] = survey.seed;
  truth["sfm_scale"] = survey.T_sfm_world.scale;
  truth["T_sfm_world"] = matrix_to_json(survey.T_sfm_world.matrix());
  truth["T_world_sfm"] = matrix_to_json(survey.T_world_sfm.matrix());
  truth["T_vins_world"] = matrix_to_json(survey.T_vins_world.matrix());
  nlohmann::json images = nlohmann::json::array();
  for (const auto& im : survey.images)
    images.push_back({{"name", im.name}, {"timestamp", im.timestamp}, {"T_world_cam", matrix_to_json(im.T_world_cam.matrix())}});
  truth["images"] = std::move(images);
  const auto file = dir / "drone_truth.json";
  std::ofstream out(file);
  if (!out) throw InputError(file.string() + ": cannot open file for writing");
  out << truth.dump(2) << "\n";
  if (!out) throw InputError(file.string() + ": write error");
}

}  // namespace cairn::sim
