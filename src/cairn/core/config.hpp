#pragma once
// Configuration structs describe their fields once, in a `visit` member:
//
//   struct VoxelGridConfig {
//     double res_voxel = 0.03;
//     template <class V> void visit(V& v) { v("res_voxel", res_voxel, "voxel size [m] (Table 3)"); }
//   };
//
// Nested configs are visited the same way (v("ground", ground, "...")). From that one description
// come YAML loading (unknown keys are errors), `--set a.b.c=value` overrides, a documented YAML
// dump and a JSON copy for result files.
#include <yaml-cpp/yaml.h>

#include <concepts>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cairn/core/error.hpp"

namespace cairn::config {

struct Probe {
  template <class T>
  void operator()(const char*, T&, const char*) {}
};
template <class T>
concept Visitable = requires(T& t, Probe& p) { t.visit(p); };

// ---- YAML dump (with the documentation as comments) ------------------------------------------
class YamlDumper {
 public:
  explicit YamlDumper(YAML::Emitter& out) : out_(out) {}
  template <class T>
  void operator()(const char* key, T& value, const char* doc) {
    out_ << YAML::Key << key << YAML::Value;
    if constexpr (Visitable<T>) {
      out_ << YAML::Comment(doc) << YAML::BeginMap;
      value.visit(*this);
      out_ << YAML::EndMap;
    } else {
      out_ << value << YAML::Comment(doc);
    }
  }

 private:
  YAML::Emitter& out_;
};

template <Visitable C>
std::string to_yaml(C config) {
  YAML::Emitter out;
  out.SetDoublePrecision(10);
  out << YAML::BeginMap;
  YamlDumper d(out);
  config.visit(d);
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

// ---- YAML load -------------------------------------------------------------------------------
class YamlLoader {
 public:
  YamlLoader(const YAML::Node& node, std::string path) : node_(node), path_(std::move(path)) {}
  template <class T>
  void operator()(const char* key, T& value, const char*) {
    known_.emplace_back(key);
    const YAML::Node child = node_[key];
    if (!child) return;
    const std::string where = path_.empty() ? key : path_ + "." + key;
    if constexpr (Visitable<T>) {
      if (!child.IsMap()) throw ConfigError("config: '" + where + "' must be a mapping");
      YamlLoader sub(child, where);
      value.visit(sub);
      sub.check_unknown();
    } else {
      try {
        value = child.as<T>();
      } catch (const YAML::Exception&) {
        throw ConfigError("config: '" + where + "' has an invalid value '" + YAML::Dump(child) + "'");
      }
    }
  }
  void check_unknown() const;

 private:
  YAML::Node node_;
  std::string path_;
  std::vector<std::string> known_;
};

template <Visitable C>
void apply_yaml(C& config, const YAML::Node& root) {
  if (!root || root.IsNull()) return;
  if (!root.IsMap()) throw ConfigError("config: the top level must be a mapping");
  YamlLoader loader(root, "");
  config.visit(loader);
  loader.check_unknown();
}

/// Loads a YAML file into `config` (fields absent from the file keep their values).
template <Visitable C>
void load_yaml_file(C& config, const std::filesystem::path& file) {
  YAML::Node root;
  try {
    if (!std::filesystem::exists(file)) throw ConfigError(file.string() + ": config file not found");
    root = YAML::LoadFile(file.string());
  } catch (const YAML::Exception& e) {
    throw ConfigError(file.string() + ": invalid YAML: " + e.what());
  }
  try {
    apply_yaml(config, root);
  } catch (const ConfigError& e) {
    throw ConfigError(file.string() + ": " + e.what());
  }
}

/// Applies "a.b.c=value" (value in YAML syntax) to the field at that path.
template <Visitable C>
void apply_override(C& config, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError("config override '" + assignment + "': expected key.path=value");
  const std::string path = assignment.substr(0, eq);
  YAML::Node root;
  YAML::Node cur = root;
  std::size_t start = 0;
  std::vector<std::string> parts;
  for (std::size_t dot; (dot = path.find('.', start)) != std::string::npos; start = dot + 1)
    parts.push_back(path.substr(start, dot - start));
  parts.push_back(path.substr(start));
  YAML::Node value;
  try {
    value = YAML::Load(assignment.substr(eq + 1));
  } catch (const YAML::Exception& e) {
    throw ConfigError("config override '" + assignment + "': " + e.what());
  }
  // Build {a: {b: {c: value}}} and load it like a file.
  YAML::Node nested = value;
  for (auto it = parts.rbegin(); it != parts.rend(); ++it) {
    YAML::Node m(YAML::NodeType::Map);
    m[*it] = nested;
    nested = m;
  }
  apply_yaml(config, nested);
}

// ---- JSON copy ---------------------------------------------------------------------------------
class JsonDumper {
 public:
  explicit JsonDumper(nlohmann::json& out) : out_(out) {}
  template <class T>
  void operator()(const char* key, T& value, const char*) {
    if constexpr (Visitable<T>) {
      nlohmann::json sub = nlohmann::json::object();
      JsonDumper d(sub);
      value.visit(d);
      out_[key] = sub;
    } else {
      out_[key] = value;
    }
  }

 private:
  nlohmann::json& out_;
};

template <Visitable C>
nlohmann::json to_json(C config) {
  nlohmann::json out = nlohmann::json::object();
  JsonDumper d(out);
  config.visit(d);
  return out;
}

}  // namespace cairn::config
