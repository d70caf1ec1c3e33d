#pragma once
// A thin RAII layer over SQLite's C API for the object database: a connection and prepared
// statements whose errors become InputErrors naming the database file.
#include <sqlite3.h>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace cairn::sqlite {

class Statement;

class Connection {
 public:
  /// flags: SQLITE_OPEN_READONLY or SQLITE_OPEN_READWRITE [| SQLITE_OPEN_CREATE].
  Connection(std::string path, int flags);
  ~Connection();
  Connection(Connection&& o) noexcept;
  Connection& operator=(Connection&& o) noexcept;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  /// Runs SQL without results (several statements allowed).
  void exec(const std::string& sql) const;
  [[nodiscard]] Statement prepare(const std::string& sql) const;
  /// The first column of the first row as an integer / text (pragmas, counts).
  [[nodiscard]] std::int64_t scalar_int(const std::string& sql) const;
  [[nodiscard]] std::string scalar_text(const std::string& sql) const;
  [[nodiscard]] std::int64_t last_insert_id() const;
  [[nodiscard]] const std::string& path() const { return path_; }
  /// Throws InputError "<path>: <what>: <sqlite message>".
  [[noreturn]] void fail(const std::string& what) const;
  [[nodiscard]] sqlite3* handle() const { return db_; }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

class Statement {
 public:
  Statement(const Connection& db, const std::string& sql);
  ~Statement();
  Statement(Statement&& o) noexcept;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  Statement& operator=(Statement&&) = delete;

  Statement& bind(int i, std::int64_t v);
  Statement& bind(int i, double v);
  Statement& bind(int i, const std::string& v);
  Statement& bind_blob(int i, std::span<const std::byte> v);
  Statement& bind_null(int i);
  /// Next row: true while there is one; throws on errors.
  bool step();
  /// Runs a statement without results.
  void run();
  void reset();

  [[nodiscard]] bool is_null(int col) const;
  [[nodiscard]] std::int64_t column_int(int col) const;
  [[nodiscard]] double column_double(int col) const;
  [[nodiscard]] std::string column_text(int col) const;
  [[nodiscard]] std::vector<std::byte> column_blob(int col) const;

 private:
  const Connection* db_;
  sqlite3_stmt* stmt_ = nullptr;
  std::string sql_;
};

/// BEGIN IMMEDIATE … COMMIT; rolls back when destroyed without commit().
class Transaction {
 public:
  explicit Transaction(const Connection& db);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void commit();

 private:
  const Connection& db_;
  bool done_ = false;
};

}  // namespace cairn::sqlite
