#pragma once
// Locating the shared real data sets (../shared/data/real) from tests.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

namespace cairn::test {

/// shared/ folder: $CAIRN_SHARED_DIR if set, else the path configured at build time.
inline std::filesystem::path shared_dir() {
  if (const char* env = std::getenv("CAIRN_SHARED_DIR")) return env;
  return CAIRN_SHARED_DIR;
}

inline std::filesystem::path real_data(const std::filesystem::path& relative) {
  return shared_dir() / "data" / "real" / relative;
}

/// In CI (environment CI set and not "false", as .ci/run runs) a missing data set fails the test
/// instead of skipping it.
inline bool in_ci() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && *ci != '\0' && std::string(ci) != "false";
}

/// Removes an SQLite database file with its WAL and shared-memory files.
inline void remove_db(const std::filesystem::path& f) {
  for (const char* side : {"", "-wal", "-shm"}) std::filesystem::remove(f.string() + side);
}

/// A fresh, empty temporary directory for one test, private to this process: ctest runs the
/// tests of one executable as parallel processes, so a shared name let one test delete the
/// directory another was reading. Every directory handed out is removed when the process exits.
inline std::filesystem::path temp_dir(const std::string& name) {
  static std::mutex mutex;
  static std::vector<std::filesystem::path> made;
  auto dir = std::filesystem::temp_directory_path() /
             ("cairn_test_" + name + "_" + std::to_string(::getpid()));
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  std::filesystem::create_directories(dir);
  const std::lock_guard lock(mutex);
  if (made.empty())
    std::atexit([] {
      std::error_code ignored;
      for (const auto& d : made) std::filesystem::remove_all(d, ignored);
    });
  made.push_back(dir);
  return dir;
}

}  // namespace cairn::test

/// Skips the test (with a message) when the shared real data set is not present; fails it in CI.
#define CAIRN_REQUIRE_REAL_DATA(relative)                                                      \
  do {                                                                                         \
    if (!std::filesystem::exists(::cairn::test::real_data(relative))) {                        \
      if (::cairn::test::in_ci()) GTEST_FAIL() << "CI: real data not found: " << ::cairn::test::real_data(relative); \
      GTEST_SKIP() << "real data not found: " << ::cairn::test::real_data(relative);           \
    }                                                                                          \
  } while (0)
