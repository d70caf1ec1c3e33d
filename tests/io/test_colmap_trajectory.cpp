// COLMAP text model and TUM trajectory: exact round trips, camera centres, malformed input.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/core/io/colmap.hpp"
#include "cairn/core/io/trajectory.hpp"
#include "support/test_data.hpp"

namespace cairn::io {
namespace {

namespace fs = std::filesystem;

fs::path scratch_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return test::temp_dir(std::string("colmap_tum_") + info->name());
}

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream(file, std::ios::binary) << text;
}

/// Expects InputError whose message names the file and contains `needle`.
template <class F>
void expect_input_error(F&& f, const fs::path& file, const std::string& needle) {
  try {
    f();
    FAIL() << "no InputError for " << file;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(file.filename().string()), std::string::npos) << msg;
    EXPECT_NE(msg.find(needle), std::string::npos) << msg;
  }
}

ColmapModel random_model(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  ColmapModel m;
  m.cameras.push_back({1, "PINHOLE", 752, 480, {458.654, 457.296, 367.215, 248.375}});
  m.cameras.push_back({7, "SIMPLE_RADIAL", 1920, 1080, {1200.5, 960.0, 540.0, -0.0123456789}});
  for (std::uint32_t i = 0; i < 5; ++i) {
    ColmapImage im;
    im.id = i + 1;
    im.q_cam_world = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    im.t_cam_world = {u(rng), u(rng), u(rng) * 1e-7};
    im.camera_id = i % 2 == 0 ? 1 : 7;
    im.name = "dir/frame_" + std::to_string(i) + ".png";
    if (i != 2) {  // image 2 keeps an empty POINTS2D line
      for (int k = 0; k < 4; ++k) im.points2d.push_back({{u(rng) + 200, u(rng) + 200}, k == 3 ? -1 : k + 1});
    }
    m.images.push_back(im);
  }
  for (std::uint64_t k = 1; k <= 3; ++k) {
    ColmapPoint3D p;
    p.id = k;
    p.xyz = {u(rng), u(rng) / 3.0, std::nextafter(u(rng), 1e300)};
    p.color = {static_cast<std::uint8_t>(k * 80), 0, 255};
    p.error = 0.1 * static_cast<double>(k) + 1e-17;
    p.track = {{1, static_cast<std::uint32_t>(k - 1)}, {2, static_cast<std::uint32_t>(k - 1)}};
    m.points.push_back(p);
  }
  return m;
}

TEST(Colmap, ExactRoundTrip) {
  const auto dir = scratch_dir() / "sparse";
  const ColmapModel model = random_model(42);
  write_colmap_text(dir, model);
  ASSERT_TRUE(fs::exists(dir / "cameras.txt"));
  const ColmapModel back = read_colmap_text(dir);
  EXPECT_TRUE(back == model);
  ASSERT_EQ(back.images.size(), model.images.size());
  EXPECT_TRUE(back.images[2].points2d.empty());
  // Writing what was read gives the same bytes.
  write_colmap_text(dir / "again", back);
  for (const char* f : {"cameras.txt", "images.txt", "points3D.txt"}) {
    std::ifstream a(dir / f), b(dir / "again" / f);
    const std::string sa((std::istreambuf_iterator<char>(a)), {}), sb((std::istreambuf_iterator<char>(b)), {});
    EXPECT_EQ(sa, sb) << f;
  }
}

TEST(Colmap, CameraCentreAndPose) {
  ColmapImage im;
  const Eigen::Matrix3d R_world_cam = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d C(1.5, -2.0, 12.0);
  im.q_cam_world = Eigen::Quaterniond(R_world_cam.transpose());
  im.t_cam_world = -(R_world_cam.transpose() * C);
  EXPECT_LT((im.center() - C).norm(), 1e-12);
  const Eigen::Vector3d X(0.3, 0.2, 0.1);
  EXPECT_LT((im.T_world_cam() * (im.rotation_cam_world() * X + im.t_cam_world) - X).norm(), 1e-12);
  const Eigen::Vector3d Xc = im.rotation_cam_world() * C + im.t_cam_world;
  EXPECT_LT(Xc.norm(), 1e-12);  // the centre projects to the camera origin
}

TEST(Colmap, ReadsCommentsCrlfAndEmptyPointLines) {
  const auto dir = scratch_dir();
  write_text(dir / "cameras.txt", "# comment\r\n\r\n3 SIMPLE_PINHOLE 100 50 80 50 25\r\n");
  write_text(dir / "images.txt",
             "# header\n1 1 0 0 0 0.5 -1 2 3 a.jpg\n\n2 0 1 0 0 0 0 0 3 b.jpg\n10.5 20.25 -1 11 21 4\n");
  write_text(dir / "points3D.txt", "# none\n4 1 2 3 10 20 30 0.5 2 1\n");
  const auto m = read_colmap_text(dir);
  ASSERT_EQ(m.cameras.size(), 1u);
  EXPECT_EQ(m.cameras[0].params.size(), 3u);
  ASSERT_EQ(m.images.size(), 2u);
  EXPECT_TRUE(m.images[0].points2d.empty());
  ASSERT_EQ(m.images[1].points2d.size(), 2u);
  EXPECT_EQ(m.images[1].points2d[0].point3d_id, -1);
  EXPECT_EQ(m.images[1].points2d[1].point3d_id, 4);
  EXPECT_EQ(m.images[1].name, "b.jpg");
  ASSERT_EQ(m.points.size(), 1u);
  EXPECT_EQ(m.points[0].color, (Rgb{10, 20, 30}));
  ASSERT_EQ(m.points[0].track.size(), 1u);
  EXPECT_EQ(m.points[0].track[0].image_id, 2u);
  const auto cloud = colmap_points_cloud(m);
  ASSERT_EQ(cloud.size(), 1u);
  EXPECT_EQ(cloud.points[0], Eigen::Vector3f(1, 2, 3));
}

TEST(Colmap, MalformedInputNamesFileAndLine) {
  const auto dir = scratch_dir();
  const auto cams = dir / "cameras.txt", imgs = dir / "images.txt", pts = dir / "points3D.txt";
  write_text(cams, "1 PINHOLE 10 10 5 5 5\n");
  expect_input_error([&] { read_colmap_cameras(cams); }, cams, "line 1");
  write_text(cams, "# c\n1 FISHY 10 10 5\n");
  expect_input_error([&] { read_colmap_cameras(cams); }, cams, "unknown camera model");
  write_text(cams, "1 PINHOLE ten 10 5 5 5 5\n");
  expect_input_error([&] { read_colmap_cameras(cams); }, cams, "WIDTH");
  write_text(cams, "1 PINHOLE 10 10 5 5 5 5\n1 PINHOLE 10 10 5 5 5 5\n");
  expect_input_error([&] { read_colmap_cameras(cams); }, cams, "line 2: duplicate");
  write_text(imgs, "1 1 0 0 0 0 0 0 1\n\n");
  expect_input_error([&] { read_colmap_images(imgs); }, imgs, "line 1");
  write_text(imgs, "1 1 0 0 0 0 0 nan 1 a.png\n\n");
  expect_input_error([&] { read_colmap_images(imgs); }, imgs, "finite");
  write_text(imgs, "1 0 0 0 0 0 0 0 1 a.png\n\n");
  expect_input_error([&] { read_colmap_images(imgs); }, imgs, "zero length");
  write_text(imgs, "# x\n1 1 0 0 0 0 0 0 1 a.png\n1 2 3 4\n");
  expect_input_error([&] { read_colmap_images(imgs); }, imgs, "line 3");
  write_text(pts, "1 0 0 0 1 2 3 0.1 5\n");
  expect_input_error([&] { read_colmap_points3d(pts); }, pts, "line 1");
  write_text(pts, "1 0 0 0 1 2 300 0.1\n");
  expect_input_error([&] { read_colmap_points3d(pts); }, pts, "'300'");
  // Image referring to a camera that does not exist.
  write_text(cams, "1 PINHOLE 10 10 5 5 5 5\n");
  write_text(imgs, "1 1 0 0 0 0 0 0 2 a.png\n\n");
  write_text(pts, "");
  expect_input_error([&] { read_colmap_text(dir); }, imgs, "unknown CAMERA_ID");
  expect_input_error([&] { read_colmap_text(dir / "missing"); }, dir / "missing" / "cameras.txt", "not found");
}

TEST(Colmap, WriterRejectsBadModels) {
  const auto dir = scratch_dir();
  ColmapModel m = random_model(1);
  m.images[0].name = "with space.png";
  EXPECT_THROW(write_colmap_text(dir, m), InputError);
  m = random_model(1);
  m.cameras[0].params.pop_back();
  EXPECT_THROW(write_colmap_text(dir, m), InputError);
}

TEST(Tum, ExactRoundTrip) {
  const auto file = scratch_dir() / "traj.txt";
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<TrajectoryPose> poses;
  for (int i = 0; i < 50; ++i) {
    TrajectoryPose p;
    p.timestamp = 1.6e9 + 0.1 * i + 1e-7 * u(rng);
    p.position = {100 * u(rng), 1e-9 * u(rng), u(rng) / 3};
    p.orientation = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    poses.push_back(p);
  }
  write_tum_trajectory(file, poses);
  const auto back = read_tum_trajectory(file);
  ASSERT_EQ(back.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) EXPECT_TRUE(back[i] == poses[i]) << i;
  // Field order: timestamp tx ty tz qx qy qz qw.
  write_text(file, "# c\n\n2.5 1 2 3 0 0 0.6 0.8\n");
  const auto one = read_tum_trajectory(file);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].timestamp, 2.5);
  EXPECT_EQ(one[0].position, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(one[0].orientation.w(), 0.8);
  EXPECT_EQ(one[0].orientation.z(), 0.6);
  EXPECT_LT((one[0].pose().linear() - Eigen::AngleAxisd(2 * std::atan2(0.6, 0.8), Eigen::Vector3d::UnitZ()).toRotationMatrix()).norm(), 1e-12);
}

TEST(Tum, MalformedLinesNameFileAndLine) {
  const auto file = scratch_dir() / "bad_traj.txt";
  write_text(file, "# header\n0 1 2 3 0 0 0 1\n1 1 2 3 0 0 1\n");
  expect_input_error([&] { read_tum_trajectory(file); }, file, "line 3");
  write_text(file, "0 1 2 x 0 0 0 1\n");
  expect_input_error([&] { read_tum_trajectory(file); }, file, "'x'");
  write_text(file, "0 1 2 3 0 0 0 0\n");
  expect_input_error([&] { read_tum_trajectory(file); }, file, "zero length");
  write_text(file, "0 1 2 inf 0 0 0 1\n");
  expect_input_error([&] { read_tum_trajectory(file); }, file, "finite");
  expect_input_error([&] { read_tum_trajectory(file.parent_path() / "nope.txt"); }, file.parent_path() / "nope.txt",
                     "not found");
  std::vector<TrajectoryPose> bad(1);
  bad[0].position.x() = std::nan("");
  EXPECT_THROW(write_tum_trajectory(file, bad), InputError);
}

}  // namespace
}  // namespace cairn::io
