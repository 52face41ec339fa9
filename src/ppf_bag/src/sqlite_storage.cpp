// rosbag2 sqlite3 storage. Writes the Humble layout (schema version 3); reads Humble, Jazzy
// (schema 4: topics.type_description_hash, message_definitions) and pre-Humble bags (no schema
// table), addressing columns by name so extra columns do not matter.
#include <sqlite3.h>

#include <limits>
#include <map>
#include <set>

#include "file_io.hpp"
#include "storage.hpp"

namespace ppf::bag::detail {
namespace {

class Db {
 public:
  Db(const std::string& path, int flags) : path_(path) {
    const int rc = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
    if (rc != SQLITE_OK) {
      const std::string msg = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
      sqlite3_close(db_);
      db_ = nullptr;
      throw BagError("cannot open sqlite3 database '" + path + "': " + msg);
    }
    sqlite3_extended_result_codes(db_, 1);
  }
  ~Db() { sqlite3_close(db_); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  sqlite3* get() const { return db_; }
  const std::string& path() const { return path_; }

  [[noreturn]] void Fail(const std::string& what) const {
    throw BagError("sqlite3 '" + path_ + "': " + what + ": " + sqlite3_errmsg(db_));
  }
  void Exec(const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string msg = err ? err : "unknown error";
      sqlite3_free(err);
      throw BagError("sqlite3 '" + path_ + "': " + msg + " (in: " + sql + ")");
    }
  }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

class Stmt {
 public:
  Stmt(Db& db, const std::string& sql) : db_(&db) {
    if (sqlite3_prepare_v2(db.get(), sql.c_str(), -1, &st_, nullptr) != SQLITE_OK) {
      db.Fail("cannot prepare '" + sql + "'");
    }
  }
  ~Stmt() { sqlite3_finalize(st_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  sqlite3_stmt* get() const { return st_; }
  // true = row available, false = done; errors (corrupt file, ...) throw.
  bool Step() {
    const int rc = sqlite3_step(st_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    db_->Fail("query failed");
  }
  void Reset() {
    sqlite3_reset(st_);
    sqlite3_clear_bindings(st_);
  }
  std::string Text(int col) const {
    const unsigned char* t = sqlite3_column_text(st_, col);
    return t ? std::string(reinterpret_cast<const char*>(t),
                           static_cast<size_t>(sqlite3_column_bytes(st_, col)))
             : std::string();
  }
  int64_t Int(int col) const { return sqlite3_column_int64(st_, col); }

 private:
  Db* db_;
  sqlite3_stmt* st_ = nullptr;
};

class SqliteWriter final : public StorageWriter {
 public:
  explicit SqliteWriter(const std::string& path)
      : db_(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) {
    // Same trade-off as rosbag2's default: fast appends, the file is consistent after Close().
    db_.Exec("PRAGMA journal_mode=MEMORY;");
    db_.Exec("PRAGMA synchronous=OFF;");
    db_.Exec(
        "CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);"
        "CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,"
        "metadata TEXT NOT NULL);"
        "CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
        "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL);"
        "CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
        "timestamp INTEGER NOT NULL, data BLOB NOT NULL);"
        "CREATE INDEX timestamp_idx ON messages (timestamp ASC);"
        "INSERT INTO schema (schema_version, ros_distro) VALUES (3, 'humble');");
    insert_topic_ = std::make_unique<Stmt>(
        db_,
        "INSERT INTO topics (name, type, serialization_format, offered_qos_profiles) "
        "VALUES (?, ?, ?, ?)");
    insert_message_ = std::make_unique<Stmt>(
        db_, "INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)");
    db_.Exec("BEGIN TRANSACTION;");
    in_txn_ = true;
  }

  ~SqliteWriter() override {
    insert_topic_.reset();
    insert_message_.reset();
  }

  void AddTopic(const TopicInfo& info) override {
    if (topic_ids_.count(info.name)) return;
    Stmt& s = *insert_topic_;
    s.Reset();
    sqlite3_bind_text(s.get(), 1, info.name.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(s.get(), 2, info.type.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(s.get(), 3, info.serialization_format.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(s.get(), 4, info.offered_qos_profiles.c_str(), -1, SQLITE_TRANSIENT);
    s.Step();
    topic_ids_[info.name] = sqlite3_last_insert_rowid(db_.get());
  }

  void Write(const TopicInfo& topic, int64_t timestamp_ns, const uint8_t* data,
             size_t size) override {
    auto it = topic_ids_.find(topic.name);
    if (it == topic_ids_.end()) throw BagError("topic '" + topic.name + "' was not added");
    Stmt& s = *insert_message_;
    s.Reset();
    sqlite3_bind_int64(s.get(), 1, it->second);
    sqlite3_bind_int64(s.get(), 2, timestamp_ns);
    sqlite3_bind_blob64(s.get(), 3, size ? data : reinterpret_cast<const uint8_t*>(""), size,
                        SQLITE_STATIC);
    s.Step();
    // Bounded transactions: a crash loses at most the last batch, not the whole recording.
    if (++pending_ >= 1000) {
      db_.Exec("COMMIT; BEGIN TRANSACTION;");
      pending_ = 0;
    }
  }

  void Close() override {
    if (!in_txn_) return;
    in_txn_ = false;
    db_.Exec("COMMIT;");
    insert_topic_.reset();
    insert_message_.reset();
  }

 private:
  Db db_;
  std::unique_ptr<Stmt> insert_topic_, insert_message_;
  std::map<std::string, int64_t> topic_ids_;
  size_t pending_ = 0;
  bool in_txn_ = false;
};

class SqliteReader final : public StorageReader {
 public:
  explicit SqliteReader(const std::string& path) : db_(Open(path)) {
    info_.storage = Storage::kSqlite3;
    std::set<std::string> tables;
    {
      Stmt s(db_, "SELECT name FROM sqlite_master WHERE type='table'");
      while (s.Step()) tables.insert(s.Text(0));
    }
    if (!tables.count("topics") || !tables.count("messages")) {
      throw BagError("'" + path + "' is not a rosbag2 sqlite3 bag (no topics/messages table)");
    }
    if (tables.count("schema")) {
      Stmt s(db_, "SELECT schema_version, ros_distro FROM schema ORDER BY schema_version DESC");
      if (s.Step()) {
        schema_version_ = static_cast<int>(s.Int(0));
        ros_distro_ = s.Text(1);
      }
    }
    std::set<std::string> cols;
    {
      Stmt s(db_, "PRAGMA table_info(topics)");
      while (s.Step()) cols.insert(s.Text(1));
    }
    for (const char* c : {"id", "name", "type"}) {
      if (!cols.count(c)) throw BagError("'" + path + "' topics table has no '" + c + "' column");
    }
    const std::string fmt = cols.count("serialization_format") ? "serialization_format" : "''";
    const std::string qos = cols.count("offered_qos_profiles") ? "offered_qos_profiles" : "''";
    std::map<int64_t, size_t> index;
    {
      Stmt s(db_, "SELECT id, name, type, " + fmt + ", " + qos + " FROM topics ORDER BY id");
      while (s.Step()) {
        TopicStats t;
        t.info.name = s.Text(1);
        t.info.type = s.Text(2);
        t.info.serialization_format = s.Text(3);
        t.info.offered_qos_profiles = s.Text(4);
        t.message_count = 0;
        index[s.Int(0)] = info_.topics.size();
        topic_names_[s.Int(0)] = t.info.name;
        info_.topics.push_back(t);
      }
    }
    {
      Stmt s(db_,
             "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages "
             "GROUP BY topic_id");
      bool any = false;
      while (s.Step()) {
        auto it = index.find(s.Int(0));
        if (it == index.end()) {
          throw BagError("'" + path + "' has messages on topic id " + std::to_string(s.Int(0)) +
                         " which is not in the topics table");
        }
        const uint64_t n = static_cast<uint64_t>(s.Int(1));
        info_.topics[it->second].message_count = n;
        info_.message_count += n;
        if (!any || s.Int(2) < info_.start_ns) info_.start_ns = s.Int(2);
        if (!any || s.Int(3) > info_.end_ns) info_.end_ns = s.Int(3);
        any = true;
      }
    }
    Seek(std::numeric_limits<int64_t>::min());
  }

  const BagInfo& Info() const override { return info_; }

  void SetFilter(const std::unordered_set<std::string>& topics) override { filter_ = topics; }

  void Seek(int64_t timestamp_ns) override {
    std::string sql = "SELECT topic_id, timestamp, data FROM messages WHERE timestamp >= ?";
    if (!filter_.empty()) {
      std::string ids;
      for (const auto& [id, name] : topic_names_) {
        if (filter_.count(name)) ids += (ids.empty() ? "" : ",") + std::to_string(id);
      }
      sql += " AND topic_id IN (" + ids + ")";
    }
    sql += " ORDER BY timestamp, id";
    query_.reset();
    query_ = std::make_unique<Stmt>(db_, sql);
    sqlite3_bind_int64(query_->get(), 1, timestamp_ns);
  }

  bool Next(Message& out) override {
    if (!query_->Step()) return false;
    auto it = topic_names_.find(query_->Int(0));
    if (it == topic_names_.end()) {
      throw BagError("'" + db_.path() + "' message refers to unknown topic id " +
                     std::to_string(query_->Int(0)));
    }
    out.topic = it->second;
    out.timestamp_ns = query_->Int(1);
    const auto* p = static_cast<const uint8_t*>(sqlite3_column_blob(query_->get(), 2));
    const int n = sqlite3_column_bytes(query_->get(), 2);
    out.data.assign(p, p + (p ? n : 0));
    return true;
  }

 private:
  static Db Open(const std::string& path) {
    if (!IsRegularFile(path)) throw BagError("cannot open '" + path + "': no such file");
    return Db(path, SQLITE_OPEN_READONLY);
  }

  Db db_;
  BagInfo info_;
  int schema_version_ = 0;
  std::string ros_distro_;
  std::map<int64_t, std::string> topic_names_;
  std::unordered_set<std::string> filter_;
  std::unique_ptr<Stmt> query_;
};

}  // namespace

std::unique_ptr<StorageWriter> MakeSqliteWriter(const std::string& path) {
  return std::make_unique<SqliteWriter>(path);
}

std::unique_ptr<StorageReader> OpenSqlite(const std::string& path) {
  return std::make_unique<SqliteReader>(path);
}

}  // namespace ppf::bag::detail
