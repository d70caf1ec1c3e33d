#pragma once
// The ROS side of run_bag.hpp: plain data in and out of a rosbag through Debian's rosbag_storage,
// no cairn types. Its source is compiled as C++17 (Debian's ROS 1 message headers use
// std::allocator<void>::rebind, gone in C++20; PITFALLS.md), so this header is C++17 too.
// Every failure — not a bag, a truncated message, a missing field — is a cairn::InputError
// naming the bag.
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace cairn::bag::file {

struct Transform {
  std::array<double, 3> t{0.0, 0.0, 0.0};
  std::array<double, 4> q{0.0, 0.0, 0.0, 1.0};  // x y z w
};

struct FrameTransform {
  std::string parent, child;
  Transform T;  // T_parent_child
};

/// A PointCloud2 of float32 x y z with optional float32 `time` (relative to the stamp) and
/// uint16 `ring` (a LiDAR sweep, Velodyne driver layout), or optional packed `rgb`.
struct Cloud {
  double stamp = 0.0;
  std::string frame;
  std::vector<float> xyz;              // 3 per point
  std::vector<float> time;             // empty or 1 per point
  std::vector<std::uint16_t> ring;     // empty or 1 per point
  std::vector<std::uint8_t> rgb;       // empty or 3 per point
};

/// An edit of the map by another stage (mapping/map_edit.hpp; kind remove_sphere, remove_near or
/// insert), e.g. a grasped object's points removed (Sec. 4.5).
struct MapEdit {
  std::string kind;
  std::array<double, 3> center{0.0, 0.0, 0.0};
  double radius = 0.0, distance = 0.0;
  Cloud points;
};

/// One message read back; `kind` tells which members hold it.
struct Message {
  enum class Kind { text, transforms, odometry, joints, cloud };
  Kind kind = Kind::text;
  std::string topic, type;
  double stamp = 0.0;  // header stamp (text: record time)
  std::string text;                         // std_msgs/String
  std::vector<FrameTransform> transforms;   // tf2_msgs/TFMessage
  std::string frame, child;                 // nav_msgs/Odometry
  Transform pose;
  std::vector<std::string> names;           // sensor_msgs/JointState
  std::vector<double> positions;
  Cloud cloud;                              // sensor_msgs/PointCloud2 (points only when decoded)
};

class Writer {
 public:
  explicit Writer(const std::string& path);  // LZ4-compressed chunks; replaces the file
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  /// `latched`: recorded as a latched topic (rosbag play re-latches it).
  void text(const std::string& topic, double t, const std::string& text, bool latched = false);
  void transforms(const std::string& topic, double t, const std::vector<FrameTransform>& transforms,
                  bool latched = false);
  void odometry(const std::string& topic, double t, const std::string& frame, const std::string& child,
                const Transform& pose);
  void joints(const std::string& topic, double t, const std::vector<std::string>& names,
              const std::vector<double>& positions);
  void cloud(const std::string& topic, const Cloud& cloud);
  void close();
  [[nodiscard]] const std::map<std::string, std::size_t>& messages() const { return messages_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::map<std::string, std::size_t> messages_;
};

/// The messages of `topics` in time order, one at a time; clouds' points are decoded only when
/// `decode_clouds` (otherwise just their stamp and frame).
class Reader {
 public:
  Reader(const std::string& path, const std::vector<std::string>& topics, bool decode_clouds);
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;
  /// The next message; false at the end.
  bool next(Message& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cairn::bag::file
