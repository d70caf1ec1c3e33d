// The cores of the nodes cairn_registration, cairn_objects and cairn_grasp without ROS
// (ros/cairn_ros/*_core.hpp) on the shared exp1 run (8 s, drone, map): the answers against the
// simulator's truth, the same library results as the CLI's calls, the database kept across
// restarts, and bad input as InputErrors.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cairn/core/error.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/run_dir.hpp"
#include "cairn/objects/pipeline.hpp"
#include "cairn/registration/drone_registration.hpp"
#include "cairn_ros/convert.hpp"
#include "cairn_ros/grasp_core.hpp"
#include "cairn_ros/objects_core.hpp"
#include "cairn_ros/registration_core.hpp"
#include "support/shared_runs.hpp"

namespace cairn::bag {
namespace {

namespace fs = std::filesystem;

// The registration protocol's bounds (apps/cairn/cmd_protocol.cpp: beyond them a success is a
// wrong alignment).
constexpr double kMaxRotationDeg = 2.0;
constexpr double kMaxTranslation = 0.10;  // [m]
// A database object's centroid (visible surface) lies this close to its stone's true centroid.
constexpr double kMaxCentroidDistance = 0.5;  // [m]

struct Site {
  fs::path dir;
  io::RunDirectory run;
  file::Cloud map;
  std::vector<Vec3d> stones;  // true centroids
  Similarity T_map_drone;
};

const Site& site() {
  static const Site s = [] {
    Site x;
    x.dir = test::shared_run(test::kExp1Drone8s);
    x.run = io::open_run_directory(x.dir / "run");
    x.map = cloud_of(io::load_cloud(x.dir / "map.ply"), 8.0, "map");
    std::ifstream site_file(x.run.truth_dir() / "site.json");
    const nlohmann::json site_json = nlohmann::json::parse(site_file);
    for (const auto& stone : site_json.at("stones")) {
      const auto& c = stone.at("centroid");
      x.stones.emplace_back(c[0].get<double>(), c[1].get<double>(), c[2].get<double>());
    }
    std::ifstream drone_json(x.run.truth_dir() / "drone.json");
    x.T_map_drone = Similarity::from_matrix(matrix_from_json(nlohmann::json::parse(drone_json).at("T_map_drone")));
    return x;
  }();
  return s;
}

Vec3d stones_centre(const Site& s) {
  Vec3d c = Vec3d::Zero();
  for (const Vec3d& p : s.stones) c += p;
  return c / double(s.stones.size());
}

TEST(RegistrationCore, RegistersTheDroneCloudLikeTheCliWithinTheProtocolsBounds) {
  const Site& s = site();
  RegistrationCore core("", {});
  EXPECT_THROW((void)core.register_drone(s.run.drone_cloud.string(), "", "", false), InputError);  // no map yet
  core.set_map(s.map);
  EXPECT_THROW((void)core.register_drone("", "", "", false), InputError);  // no drone cloud yet
  EXPECT_THROW((void)core.register_drone(s.run.drone_cloud.string(), s.run.drone_sparse.string(), "", false),
               InputError);  // an SfM model without the metric trajectory
  core.set_drone_cloud(cloud_of(io::load_cloud(s.run.drone_cloud), 8.0, "drone_sfm"));  // as on the bag's topic
  const RegistrationAnswer a = core.register_drone("", s.run.drone_sparse.string(), s.run.drone_vins.string(), false);
  ASSERT_TRUE(a.success) << a.message;
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = a.T_map_drone[std::size_t(4 * r + c)];
  const RegistrationError e = registration_error(Similarity::from_matrix(T), s.T_map_drone, stones_centre(s));
  EXPECT_LT(e.rotation_deg, kMaxRotationDeg);
  EXPECT_LT(e.translation_m, kMaxTranslation);
  EXPECT_NEAR(e.scale_ratio, 1.0, 0.01);
  EXPECT_GT(a.aligned.xyz.size(), 3000u);
  // The CLI's call on the same inputs (the map as float32, as the node receives it).
  const nlohmann::json j = nlohmann::json::parse(a.json);
  const DroneRegistration cli = register_drone(io::load_cloud(s.run.drone_cloud), points_of(s.map), s.run.drone_sparse,
                                               s.run.drone_vins, {}, {}, {});
  EXPECT_EQ(j.at("T_target_source"), to_json(cli).at("T_target_source"));
  EXPECT_EQ(j.at("matched_segments"), cli.result.matched_segments.size());
  // A drone cloud 5 % too large (its SfM points scaled, the cameras not): refused for its scale,
  // registered with estimate_scale (the service's flag reaches the library).
  file::Cloud large = cloud_of(io::load_cloud(s.run.drone_cloud), 8.0, "drone_sfm");
  for (float& v : large.xyz) v *= 1.05f;
  core.set_drone_cloud(large);
  const RegistrationAnswer refused = core.register_drone("", s.run.drone_sparse.string(), s.run.drone_vins.string(), false);
  EXPECT_FALSE(refused.success);
  EXPECT_EQ(refused.message.rfind("scale", 0), 0u) << refused.message;
  const RegistrationAnswer seven =
      core.register_drone("", s.run.drone_sparse.string(), s.run.drone_vins.string(), false, true);
  ASSERT_TRUE(seven.success) << seven.message;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = seven.T_map_drone[std::size_t(4 * r + c)];
  Similarity K;  // the 5 % the SfM points were scaled by: the estimate after it is the truth
  K.scale = 1.05;
  const RegistrationError e7 = registration_error(Similarity::from_matrix(T) * K, s.T_map_drone, stones_centre(s));
  EXPECT_NEAR(e7.scale_ratio, 1.0, 0.005);
  EXPECT_LT(e7.rotation_deg, kMaxRotationDeg);
  EXPECT_LT(e7.translation_m, kMaxTranslation);
}

/// The map merged with the registered drone cloud, as cairn_registration publishes it.
file::Cloud merged_map() {
  const Site& s = site();
  RegistrationCore core("", {});
  core.set_map(s.map);
  const RegistrationAnswer a =
      core.register_drone(s.run.drone_cloud.string(), s.run.drone_sparse.string(), s.run.drone_vins.string(), false);
  if (!a.success) throw std::runtime_error("the shared run's drone cloud does not register: " + a.message);
  return a.merged;
}

TEST(ObjectsCore, OneObjectPerStoneGraspReleaseAndKeptAcrossRestarts) {
  const Site& s = site();
  const fs::path db = test::temp_dir("objects_core") / "objects.db";
  std::int64_t largest = 0;
  Vec3d largest_centroid;
  {
    ObjectsCore core("", {}, db.string());
    EXPECT_FALSE(core.has_map());
    EXPECT_THROW((void)core.segment(0.0), InputError);
    core.set_map(s.map);
    core.set_merged_map(merged_map());
    const nlohmann::json association = nlohmann::json::parse(core.segment(8.0));
    EXPECT_EQ(association.at("segmented"), "merged");
    const std::vector<ObjectView> objects = core.objects(0.05);
    ASSERT_EQ(objects.size(), s.stones.size());
    for (std::size_t k = 0; k < s.stones.size(); ++k) {
      double nearest = 1e9;
      for (const ObjectView& o : objects)
        nearest = std::min(nearest, (Vec3d(o.centroid[0], o.centroid[1], o.centroid[2]) - s.stones[k]).norm());
      EXPECT_LT(nearest, kMaxCentroidDistance) << "stone " << k << " at " << s.stones[k].transpose();
    }
    const ObjectDatabase read(db, ObjectDatabase::Mode::read_only);
    const ObjectRecord r = object_to_grasp(read, std::nullopt);
    largest = r.id;
    largest_centroid = r.centroid;
    EXPECT_EQ(nlohmann::json::parse(core.list_json()), objects_list_json(read));
    // Grasp: stored, and the map edit of the object's own voxels (the R_obj sphere the bound).
    file::Transform G{{largest_centroid.x(), largest_centroid.y(), largest_centroid.z() + 1.0}, {0, 0, 0, 1}};
    EXPECT_THROW((void)core.grasp(9999, G, 9.0), InputError);
    // A default ROS pose (all-zero quaternion) is bad input, never a stored grasp.
    EXPECT_THROW((void)core.grasp(largest, file::Transform{{0, 0, 0}, {0, 0, 0, 0}}, 9.0), InputError);
    EXPECT_EQ(ObjectDatabase(db, ObjectDatabase::Mode::read_only).object(largest)->status, ObjectStatus::on_ground);
    const ObjectEventAnswer grasped = core.grasp(largest, G, 9.0);
    EXPECT_EQ(nlohmann::json::parse(grasped.json).at("status"), "grasped");
    ASSERT_EQ(grasped.edits.size(), 1u);
    EXPECT_EQ(grasped.edits[0].kind, "remove_near");
    EXPECT_GT(grasped.edits[0].points.xyz.size(), 0u);
    EXPECT_NO_THROW((void)from_file(grasped.edits[0]));
    EXPECT_THROW((void)core.grasp(largest, G, 9.5), InputError);  // already held
    // Release 0.5 m along x: Eq. 3 moves the centroid by exactly that.
    G.t[0] += 0.5;
    const ObjectEventAnswer released = core.release(largest, G, 10.0);
    const nlohmann::json placed = nlohmann::json::parse(released.json);
    EXPECT_EQ(placed.at("status"), "placed");
    const Vec3d moved(placed.at("centroid")[0].get<double>(), placed.at("centroid")[1].get<double>(),
                      placed.at("centroid")[2].get<double>());
    EXPECT_LT((moved - largest_centroid - Vec3d(0.5, 0, 0)).norm(), 1e-6);
    // The map still shows the stone where it was: re-alignment finds it there and reports the
    // large correction (as for a stone that rolled back), never a silent wrong pose.
    const nlohmann::json realigned = nlohmann::json::parse(core.realign(11.0)).at("realigned");
    ASSERT_EQ(realigned.size(), 1u);
    EXPECT_TRUE(realigned[0].at("found").get<bool>());
    EXPECT_TRUE(realigned[0].at("large").get<bool>());
    EXPECT_NEAR(realigned[0].at("translation_m").get<double>(), 0.5, 0.05);
  }
  // A restarted node finds every object where it left it.
  ObjectsCore again("", {}, db.string());
  const std::vector<ObjectView> objects = again.objects(0.0);
  EXPECT_EQ(objects.size(), s.stones.size());
  const auto held = std::find_if(objects.begin(), objects.end(), [&](const ObjectView& o) { return o.id == largest; });
  ASSERT_NE(held, objects.end());
  EXPECT_EQ(held->status, "placed");
}

TEST(GraspCore, PlansTheLargestObjectAndDrawsTheGripper) {
  const Site& s = site();
  const fs::path db = test::temp_dir("grasp_core") / "objects.db";
  ObjectsCore objects("", {}, db.string());
  objects.set_map(s.map);
  objects.set_merged_map(merged_map());
  (void)objects.segment(8.0);
  GraspCore core("", {}, db.string());
  EXPECT_THROW((void)core.plan(0), InputError);  // no map yet
  core.set_map(s.map);
  EXPECT_THROW((void)core.plan(9999), InputError);
  const GraspAnswer a = core.plan(0);
  const ObjectRecord largest = object_to_grasp(ObjectDatabase(db, ObjectDatabase::Mode::read_only), std::nullopt);
  EXPECT_EQ(a.object, largest.id);
  ASSERT_FALSE(a.grasps.empty());
  const nlohmann::json j = nlohmann::json::parse(a.json);
  EXPECT_EQ(j.at("grasps").size(), a.grasps.size());
  for (const PlannedGrasp& g : a.grasps) {
    ASSERT_EQ(g.parts.size(), 3u);  // palm and two jaws
    const Eigen::Isometry3d T = from_file(g.T_map_gripper);
    EXPECT_LT((T.translation() - largest.centroid).norm(), 2.0);
    // Every box has a volume (a degenerate part would draw nothing).
    for (const GripperBox& b : g.parts) EXPECT_GT(b.size[0] * b.size[1] * b.size[2], 0.0);
  }
}

TEST(StageCores, BadSettingsAreErrors) {
  EXPECT_THROW(RegistrationCore("", {"registration.no_such_key=1"}), ConfigError);
  EXPECT_THROW(ObjectsCore("", {}, ""), InputError);
  EXPECT_THROW(GraspCore("", {}, ""), InputError);
  const fs::path foreign = test::temp_dir("stage_cores") / "not_a_db.db";
  std::ofstream(foreign) << "not an SQLite file";
  EXPECT_THROW(ObjectsCore("", {}, foreign.string()), InputError);
  std::ifstream in(foreign);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "not an SQLite file");  // left untouched
}

}  // namespace
}  // namespace cairn::bag
