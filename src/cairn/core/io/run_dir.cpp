#include "cairn/core/io/run_dir.hpp"

#include <algorithm>
#include <charconv>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cairn/core/error.hpp"
#include "cairn/core/io/detail.hpp"
#include "cairn/core/io/io.hpp"
#include "cairn/core/io/trajectory.hpp"

namespace cairn::io {

namespace {

void append_number(std::string& out, double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof(buf), v);
  out.append(buf, end);
}

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> parts;
  std::string cur;
  for (char ch : line) {
    if (ch == sep) {
      parts.push_back(cur);
      cur.clear();
    } else if (ch != '\r') {
      cur += ch;
    }
  }
  parts.push_back(cur);
  return parts;
}

double number(const std::filesystem::path& file, std::size_t line, const std::string& token) {
  double v = 0.0;
  if (!detail::parse_number(token, v) || !std::isfinite(v)) {
    detail::fail(file, "line " + std::to_string(line) + ": '" + token + "' is not a finite number");
  }
  return v;
}

nlohmann::json read_json(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": missing (not a run directory?)");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(file.string() + ": invalid JSON: " + e.what());
  }
}

constexpr char kNpyMagic[] = "\x93NUMPY";
constexpr std::size_t kNpyMagicSize = 6;

}  // namespace

void write_joint_states(const std::filesystem::path& file, const std::vector<JointState>& states) {
  std::string out = "time";
  const std::vector<std::string> names = states.empty() ? std::vector<std::string>{} : states.front().names;
  for (const auto& n : names) out.append(",").append(n);
  out += "\n";
  for (const auto& s : states) {
    if (s.names != names) throw InputError(file.string() + ": joint states with differing joints");
    append_number(out, s.time);
    for (double v : s.positions) {
      out += ',';
      append_number(out, v);
    }
    out += '\n';
  }
  detail::write_file(file, out);
}

std::vector<JointState> read_joint_states(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": missing");
  std::string line;
  if (!std::getline(in, line)) detail::fail(file, "empty file (expected a 'time,...' header)");
  const auto header = split(line, ',');
  if (header.empty() || header[0] != "time") detail::fail(file, "line 1: header must start with 'time'");
  const std::vector<std::string> names(header.begin() + 1, header.end());
  std::vector<JointState> states;
  for (std::size_t ln = 2; std::getline(in, line); ++ln) {
    if (line.empty() || line == "\r") continue;
    const auto parts = split(line, ',');
    if (parts.size() != header.size()) {
      detail::fail(file, "line " + std::to_string(ln) + ": expected " + std::to_string(header.size()) +
                             " values, got " + std::to_string(parts.size()));
    }
    JointState s;
    s.time = number(file, ln, parts[0]);
    s.names = names;
    for (std::size_t k = 1; k < parts.size(); ++k) s.positions.push_back(number(file, ln, parts[k]));
    if (!states.empty() && s.time < states.back().time) {
      detail::fail(file, "line " + std::to_string(ln) + ": time goes backwards");
    }
    states.push_back(std::move(s));
  }
  return states;
}

void write_stamped_poses(const std::filesystem::path& file, const std::vector<StampedPose>& poses) {
  std::vector<TrajectoryPose> tum;
  tum.reserve(poses.size());
  for (const auto& p : poses) {
    tum.push_back({p.time, p.pose.translation(), Eigen::Quaterniond(p.pose.linear()).normalized()});
  }
  write_tum_trajectory(file, tum);
}

std::vector<StampedPose> read_stamped_poses(const std::filesystem::path& file) {
  std::vector<StampedPose> poses;
  for (const auto& p : read_tum_trajectory(file)) {
    if (!poses.empty() && p.timestamp <= poses.back().time) {
      throw InputError(file.string() + ": timestamps must increase (at t = " + std::to_string(p.timestamp) + ")");
    }
    poses.push_back({p.timestamp, p.pose()});
  }
  return poses;
}

void write_scan_index(const std::filesystem::path& file, const std::vector<ScanInfo>& scans) {
  std::string out = "sensor,index,t_start,t_end,num_points,file\n";
  for (const auto& s : scans) {
    out.append(s.sensor).append(",").append(std::to_string(s.index)).append(",");
    append_number(out, s.t_start);
    out += ',';
    append_number(out, s.t_end);
    out.append(",").append(std::to_string(s.num_points)).append(",").append(s.file).append("\n");
  }
  detail::write_file(file, out);
}

std::vector<ScanInfo> read_scan_index(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": missing");
  std::string line;
  std::getline(in, line);
  if (split(line, ',').size() != 6) detail::fail(file, "line 1: expected the header sensor,index,t_start,t_end,num_points,file");
  std::vector<ScanInfo> scans;
  for (std::size_t ln = 2; std::getline(in, line); ++ln) {
    if (line.empty() || line == "\r") continue;
    const auto p = split(line, ',');
    if (p.size() != 6) detail::fail(file, "line " + std::to_string(ln) + ": expected 6 values");
    ScanInfo s;
    s.sensor = p[0];
    const std::string at = "line " + std::to_string(ln) + ": ";
    const std::size_t index = detail::parse_count(p[1], file, at + "sweep index");
    if (index > std::size_t(std::numeric_limits<int>::max())) detail::fail(file, at + "sweep index too large");
    s.index = static_cast<int>(index);
    s.t_start = number(file, ln, p[2]);
    s.t_end = number(file, ln, p[3]);
    s.num_points = detail::parse_count(p[4], file, at + "point count");
    if (s.t_end < s.t_start) detail::fail(file, at + "invalid sweep (t_end before t_start)");
    s.file = p[5];
    scans.push_back(std::move(s));
  }
  std::stable_sort(scans.begin(), scans.end(), [](const ScanInfo& a, const ScanInfo& b) { return a.t_start < b.t_start; });
  return scans;
}

void write_npy_int32(const std::filesystem::path& file, const std::vector<std::int32_t>& values) {
  std::string header = "{'descr': '<i4', 'fortran_order': False, 'shape': (" + std::to_string(values.size()) + ",), }";
  const std::size_t unpadded = kNpyMagicSize + 4 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header += '\n';
  std::string out(kNpyMagic, kNpyMagicSize);
  out += '\x01';
  out += '\x00';
  const auto len = static_cast<std::uint16_t>(header.size());
  out += static_cast<char>(len & 0xFF);
  out += static_cast<char>(len >> 8);
  out += header;
  const std::size_t offset = out.size();
  out.resize(offset + 4 * values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    const auto u = static_cast<std::uint32_t>(values[i]);
    for (int b = 0; b < 4; ++b) out[offset + 4 * i + static_cast<std::size_t>(b)] = static_cast<char>((u >> (8 * b)) & 0xFF);
  }
  detail::write_file(file, out);
}

std::vector<std::int32_t> read_npy_int32(const std::filesystem::path& file) {
  const std::string bytes = detail::read_file(file);
  const detail::NpyHeader h = detail::parse_npy_header(bytes, file);
  if (h.descr != "<i4" || h.shape.size() != 1) detail::fail(file, "expected a 1-D little-endian int32 array ('<i4')");
  const std::size_t count = h.shape[0], data = h.data_start;
  if (bytes.size() != data + 4 * count) detail::fail_truncated(file, count, (bytes.size() - data) / 4, "labels");
  std::vector<std::int32_t> values(count);
  for (std::size_t i = 0; i < count; ++i) {
    std::uint32_t u = 0;
    for (int b = 0; b < 4; ++b) u |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[data + 4 * i + static_cast<std::size_t>(b)])) << (8 * b);
    values[i] = static_cast<std::int32_t>(u);
  }
  return values;
}

PointCloud RunDirectory::read_scan(const ScanInfo& scan) const {
  const auto file = root / scan.file;
  PointCloud cloud = read_cloud(file).cloud;
  if (cloud.size() != scan.num_points) {
    throw InputError(file.string() + ": " + std::to_string(cloud.size()) + " points, the scan index says " +
                     std::to_string(scan.num_points));
  }
  if (!cloud.has_times()) throw InputError(file.string() + ": no per-point 'time' property");
  return cloud;
}

std::vector<std::int32_t> RunDirectory::read_scan_truth(const ScanInfo& scan) const {
  std::filesystem::path rel = scan.file;
  rel.replace_extension(".npy");
  const auto file = truth_dir() / rel;
  std::vector<std::int32_t> labels = read_npy_int32(file);
  if (labels.size() != scan.num_points) {
    throw InputError(file.string() + ": " + std::to_string(labels.size()) + " labels for " +
                     std::to_string(scan.num_points) + " points");
  }
  return labels;
}

RunDirectory open_run_directory(const std::filesystem::path& root) {
  if (!std::filesystem::is_directory(root)) throw InputError(root.string() + ": run directory not found");
  RunDirectory run;
  run.root = root;
  const nlohmann::json meta = read_json(root / "run.json");
  try {
    const nlohmann::json& v = meta.at("format_version");
    if (!v.is_number_integer()) throw InputError((root / "run.json").string() + ": format_version must be an integer");
    const auto version = v.get<std::int64_t>();
    if (version != kRunFormatVersion) {
      throw InputError((root / "run.json").string() + ": format_version " + std::to_string(version) +
                       " (this build reads " + std::to_string(kRunFormatVersion) + ")");
    }
    run.scenario = meta.value("scenario", "");
    if (meta.contains("seed") && !meta["seed"].is_number_unsigned())  // a double would be cast (UB)
      throw InputError((root / "run.json").string() + ": seed must be a non-negative integer");
    run.seed = meta.value("seed", std::uint64_t{0});
    run.duration = meta.value("duration", 0.0);
  } catch (const nlohmann::json::exception& e) {
    throw InputError((root / "run.json").string() + ": " + e.what());
  }
  run.robot = read_robot_model((root / "robot.json").string());
  const nlohmann::json ext = read_json(root / "extrinsics.json");
  std::string key = "T_cabin_sensor";
  try {
    for (const auto& [name, value] : ext.at(key).items()) {
      key = "T_cabin_sensor " + name;
      run.T_cabin_sensor[name] = rigid_from_matrix(matrix_from_json(value), "the matrix");
    }
  } catch (const std::exception& e) {
    throw InputError((root / "extrinsics.json").string() + ": " + key + ": " + e.what());
  }
  run.scans = read_scan_index(root / "scans" / "index.csv");
  for (const auto& s : run.scans) {
    if (!run.T_cabin_sensor.contains(s.sensor)) {
      throw InputError((root / "scans" / "index.csv").string() + ": sensor '" + s.sensor + "' has no extrinsics");
    }
  }
  run.state_estimate = read_stamped_poses(root / "state" / "cabin_poses.tum");
  if (run.state_estimate.empty()) throw InputError((root / "state" / "cabin_poses.tum").string() + ": no poses");
  run.joint_states = read_joint_states(root / "state" / "joint_states.csv");
  const auto maybe = [&](const std::filesystem::path& p) { return std::filesystem::exists(p) ? p : std::filesystem::path{}; };
  run.drone_cloud = maybe(root / "drone" / "cloud.ply");
  run.drone_sparse = maybe(root / "drone" / "sparse");
  run.drone_vins = maybe(root / "drone" / "vins_trajectory.tum");
  return run;
}

}  // namespace cairn::io
