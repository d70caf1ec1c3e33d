// TUM trajectory reader and writer.
#include "cairn/core/io/trajectory.hpp"

#include <charconv>
#include <cmath>
#include <string>

#include "cairn/core/error.hpp"
#include "cairn/core/io/detail.hpp"

namespace cairn::io {
namespace {

constexpr std::size_t kFields = 8;      // timestamp tx ty tz qx qy qz qw
constexpr std::size_t kMaxQuoted = 40;  // longest token quoted in an error message

void put(std::string& out, double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip form
  out.append(buf, end);
}

}  // namespace

Eigen::Isometry3d TrajectoryPose::pose() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = orientation.normalized().toRotationMatrix();
  T.translation() = position;
  return T;
}

void write_tum_trajectory(const std::filesystem::path& file, std::span<const TrajectoryPose> poses) {
  std::string out = "# timestamp tx ty tz qx qy qz qw\n";
  out.reserve(out.size() + poses.size() * 160);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const auto& p = poses[i];
    const auto& q = p.orientation;
    const double values[kFields] = {p.timestamp, p.position.x(), p.position.y(), p.position.z(),
                                    q.x(),       q.y(),          q.z(),          q.w()};
    for (std::size_t k = 0; k < kFields; ++k) {
      if (!std::isfinite(values[k]))
        detail::fail(file, "pose " + std::to_string(i) + " has a non-finite value");
      if (k > 0) out.push_back(' ');
      put(out, values[k]);
    }
    out.push_back('\n');
  }
  detail::write_file(file, out);
}

std::vector<TrajectoryPose> read_tum_trajectory(const std::filesystem::path& file) {
  const std::string text = detail::read_file(file);
  std::vector<TrajectoryPose> poses;
  std::size_t pos = 0, number = 0;
  while (pos < text.size()) {
    const auto end = std::min(text.find_first_of("\r\n", pos), text.size());
    const std::string_view line = std::string_view(text).substr(pos, end - pos);
    pos = end;
    if (pos < text.size() && text[pos] == '\r') ++pos;
    if (pos < text.size() && text[pos] == '\n') ++pos;
    ++number;
    const auto words = detail::split_words(line);
    if (words.empty() || words.front().front() == '#') continue;
    const std::string where = "line " + std::to_string(number) + ": ";
    if (words.size() != kFields)
      detail::fail(file, where + "expected 8 values (timestamp tx ty tz qx qy qz qw), got " +
                             std::to_string(words.size()));
    double v[kFields];
    for (std::size_t k = 0; k < kFields; ++k) {
      if (!detail::parse_number(words[k], v[k]) || !std::isfinite(v[k]))
        detail::fail(file, where + "'" + std::string(words[k].substr(0, kMaxQuoted)) + "' is not a finite number");
    }
    TrajectoryPose p;
    p.timestamp = v[0];
    p.position = {v[1], v[2], v[3]};
    p.orientation = Eigen::Quaterniond(v[7], v[4], v[5], v[6]);
    if (!(p.orientation.norm() > 1e-12)) detail::fail(file, where + "quaternion has zero length");
    poses.push_back(p);
  }
  return poses;
}

}  // namespace cairn::io
