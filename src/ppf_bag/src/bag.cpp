// Public Writer/Reader: bag directory layout, metadata.yaml, and the time-ordered merge across
// storage files.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <unordered_set>

#include "compression.hpp"
#include "file_io.hpp"
#include "mcap_format.hpp"
#include "ppf_bag/bag.hpp"
#include "storage.hpp"

namespace fs = std::filesystem;

namespace ppf::bag {

const char* StorageIdentifier(Storage storage) {
  switch (storage) {
    case Storage::kSqlite3:
      return "sqlite3";
    case Storage::kMcap:
      return "mcap";
    case Storage::kRos1:
      return "rosbag_v2";
  }
  return "unknown";
}

namespace {

std::string BagName(const std::string& dir) {
  fs::path p = fs::path(dir).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  const std::string name = p.filename().string();
  return name.empty() || name == "." || name == ".." ? "bag" : name;
}

std::string MetadataYaml(Storage storage, const std::string& file, const BagInfo& info) {
  const bool mcap = storage == Storage::kMcap;
  const int64_t start = info.message_count ? info.start_ns : 0;
  const int64_t duration = info.message_count ? info.end_ns - info.start_ns : 0;
  YAML::Emitter e;
  e << YAML::BeginMap << YAML::Key << "rosbag2_bagfile_information" << YAML::Value
    << YAML::BeginMap;
  e << YAML::Key << "version" << YAML::Value << (mcap ? 9 : 5);
  e << YAML::Key << "storage_identifier" << YAML::Value << StorageIdentifier(storage);
  e << YAML::Key << "duration" << YAML::Value << YAML::BeginMap << YAML::Key << "nanoseconds"
    << YAML::Value << duration << YAML::EndMap;
  e << YAML::Key << "starting_time" << YAML::Value << YAML::BeginMap << YAML::Key
    << "nanoseconds_since_epoch" << YAML::Value << start << YAML::EndMap;
  e << YAML::Key << "message_count" << YAML::Value << info.message_count;
  e << YAML::Key << "topics_with_message_count" << YAML::Value << YAML::BeginSeq;
  for (const auto& t : info.topics) {
    e << YAML::BeginMap << YAML::Key << "topic_metadata" << YAML::Value << YAML::BeginMap;
    e << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << t.info.name;
    e << YAML::Key << "type" << YAML::Value << YAML::DoubleQuoted << t.info.type;
    e << YAML::Key << "serialization_format" << YAML::Value << YAML::DoubleQuoted
      << t.info.serialization_format;
    e << YAML::Key << "offered_qos_profiles" << YAML::Value << YAML::DoubleQuoted
      << t.info.offered_qos_profiles;
    if (mcap) e << YAML::Key << "type_description_hash" << YAML::Value << YAML::DoubleQuoted << "";
    e << YAML::EndMap << YAML::Key << "message_count" << YAML::Value << t.message_count
      << YAML::EndMap;
  }
  e << YAML::EndSeq;
  e << YAML::Key << "compression_format" << YAML::Value << YAML::DoubleQuoted << "";
  e << YAML::Key << "compression_mode" << YAML::Value << YAML::DoubleQuoted << "";
  e << YAML::Key << "relative_file_paths" << YAML::Value << YAML::BeginSeq << file << YAML::EndSeq;
  e << YAML::Key << "files" << YAML::Value << YAML::BeginSeq << YAML::BeginMap;
  e << YAML::Key << "path" << YAML::Value << file;
  e << YAML::Key << "starting_time" << YAML::Value << YAML::BeginMap << YAML::Key
    << "nanoseconds_since_epoch" << YAML::Value << start << YAML::EndMap;
  e << YAML::Key << "duration" << YAML::Value << YAML::BeginMap << YAML::Key << "nanoseconds"
    << YAML::Value << duration << YAML::EndMap;
  e << YAML::Key << "message_count" << YAML::Value << info.message_count;
  e << YAML::EndMap << YAML::EndSeq;
  if (mcap) {
    e << YAML::Key << "custom_data" << YAML::Value << YAML::Null;
    e << YAML::Key << "ros_distro" << YAML::Value << YAML::DoubleQuoted << "";
  }
  e << YAML::EndMap << YAML::EndMap;
  if (!e.good()) throw BagError("cannot emit metadata.yaml: " + e.GetLastError());
  return std::string(e.c_str()) + "\n";
}

}  // namespace

// ---------------------------------------------------------------------------------------------
class Writer::Impl {
 public:
  Impl(const std::string& dir, const WriterOptions& options) : dir_(dir) {
    info_.storage = options.storage;
    const bool mcap = options.storage == Storage::kMcap;
    // Validate options before touching the file system.
    if (options.storage == Storage::kRos1) {
      throw BagError("ROS 1 bags can be read but not written; write sqlite3 or mcap");
    }
    if (mcap && !detail::IsSupportedCompression(options.compression)) {
      throw BagError("unsupported MCAP compression '" + options.compression +
                     "' (expected none, lz4 or zstd)");
    }
    if (!mcap && !options.compression.empty() && options.compression != "none") {
      throw BagError("sqlite3 storage does not support compression '" + options.compression + "'");
    }
    std::error_code ec;
    if (fs::exists(dir, ec)) {
      if (!fs::is_directory(dir, ec) || !fs::is_empty(dir, ec)) {
        throw BagError("cannot write bag: '" + dir + "' already exists and is not an empty directory");
      }
    } else if (!fs::create_directories(dir, ec)) {
      throw BagError("cannot create bag directory '" + dir + "': " + ec.message());
    }
    file_ = BagName(dir) + "_0" + (mcap ? ".mcap" : ".db3");
    path_ = (fs::path(dir) / file_).string();
    if (mcap) {
      storage_ = detail::MakeMcapWriter(path_, options);
    } else {
      storage_ = detail::MakeSqliteWriter(path_);
    }
  }

  void AddTopic(const TopicInfo& info) {
    Check();
    if (info.name.empty()) throw BagError("topic name must not be empty");
    auto it = index_.find(info.name);
    if (it != index_.end()) {
      const TopicInfo& old = info_.topics[it->second].info;
      if (old.type != info.type || old.serialization_format != info.serialization_format) {
        throw BagError("topic '" + info.name + "' already added with type '" + old.type +
                       "' (" + old.serialization_format + "), cannot re-add as '" + info.type +
                       "' (" + info.serialization_format + ")");
      }
      return;
    }
    storage_->AddTopic(info);
    index_[info.name] = info_.topics.size();
    info_.topics.push_back({info, 0});
  }

  void Write(const std::string& topic, int64_t t, const uint8_t* data, size_t size) {
    Check();
    auto it = index_.find(topic);
    if (it == index_.end()) throw BagError("Write on topic '" + topic + "' which was not added");
    if (size && !data) throw BagError("Write on '" + topic + "': null data");
    TopicStats& ts = info_.topics[it->second];
    storage_->Write(ts.info, t, data, size);
    ++ts.message_count;
    if (info_.message_count == 0 || t < info_.start_ns) info_.start_ns = t;
    if (info_.message_count == 0 || t > info_.end_ns) info_.end_ns = t;
    ++info_.message_count;
  }

  void Close() {
    if (closed_) return;
    closed_ = true;
    storage_->Close();
    const std::string yaml = MetadataYaml(info_.storage, file_, info_);
    const std::string meta = (fs::path(dir_) / "metadata.yaml").string();
    std::ofstream out(meta, std::ios::binary | std::ios::trunc);
    out << yaml;
    out.close();
    if (!out) throw BagError("cannot write '" + meta + "'");
  }

  const std::string& path() const { return path_; }

 private:
  void Check() const {
    if (closed_) throw BagError("writer for '" + dir_ + "' is already closed");
  }

  std::string dir_, file_, path_;
  std::unique_ptr<detail::StorageWriter> storage_;
  BagInfo info_;
  std::map<std::string, size_t> index_;
  bool closed_ = false;
};

Writer::Writer(const std::string& dir, const WriterOptions& options)
    : impl_(std::make_unique<Impl>(dir, options)) {}

Writer::~Writer() {
  try {
    if (impl_) impl_->Close();
  } catch (...) {
    // Destructors must not throw; callers who care call Close() explicitly.
  }
}

void Writer::AddTopic(const TopicInfo& info) { impl_->AddTopic(info); }
void Writer::Write(const std::string& topic, int64_t t, const uint8_t* data, size_t size) {
  impl_->Write(topic, t, data, size);
}
void Writer::Close() { impl_->Close(); }
const std::string& Writer::storage_file() const { return impl_->path(); }

// ---------------------------------------------------------------------------------------------
namespace {

Storage SniffFile(const std::string& path) {
  const std::string ext = fs::path(path).extension().string();
  if (ext == ".db3") return Storage::kSqlite3;
  if (ext == ".mcap") return Storage::kMcap;
  if (ext == ".bag") return Storage::kRos1;
  detail::InputFile f(path);
  uint8_t head[16] = {};
  if (f.size() >= 16) f.ReadAt(0, head, 16);
  if (std::memcmp(head, detail::mcap::kMagic, 8) == 0) return Storage::kMcap;
  if (std::memcmp(head, "SQLite format 3", 16) == 0) return Storage::kSqlite3;
  if (std::memcmp(head, "#ROSBAG V", 9) == 0) return Storage::kRos1;
  throw BagError("'" + path + "' is neither an MCAP file, a sqlite3 database nor a ROS 1 bag");
}

std::unique_ptr<detail::StorageReader> OpenFile(const std::string& path, Storage kind) {
  switch (kind) {
    case Storage::kMcap:
      return detail::OpenMcap(path);
    case Storage::kRos1:
      return detail::OpenRos1(path);
    case Storage::kSqlite3:
      break;
  }
  return detail::OpenSqlite(path);
}

}  // namespace

class Reader::Impl {
 public:
  explicit Impl(const std::string& path) {
    if (detail::IsDirectory(path)) {
      OpenDirectory(path);
    } else if (detail::IsRegularFile(path)) {
      const Storage kind = SniffFile(path);
      info_.storage = kind;
      sources_.push_back(OpenFile(path, kind));
    } else {
      throw BagError("no such bag: '" + path + "'");
    }
    MergeInfo();
    heads_.resize(sources_.size());
  }

  const BagInfo& Info() const { return info_; }

  void SetTopicFilter(std::vector<std::string> topics) {
    std::unordered_set<std::string> set;
    for (auto& t : topics) {
      const bool known = std::any_of(info_.topics.begin(), info_.topics.end(),
                                     [&](const TopicStats& s) { return s.info.name == t; });
      if (!known) throw BagError("topic filter names '" + t + "' which is not in the bag");
      set.insert(std::move(t));
    }
    for (auto& s : sources_) s->SetFilter(set);
    Seek(seek_);
  }

  void Seek(int64_t t) {
    seek_ = t;
    for (auto& s : sources_) s->Seek(t);
    for (auto& h : heads_) h.reset();
    exhausted_.assign(sources_.size(), false);
  }

  bool Next(Message& out) {
    size_t best = sources_.size();
    for (size_t i = 0; i < sources_.size(); ++i) {
      if (!heads_[i] && !exhausted_[i]) {
        Message m;
        if (sources_[i]->Next(m)) {
          heads_[i] = std::move(m);
        } else {
          exhausted_[i] = true;
        }
      }
      if (heads_[i] && (best == sources_.size() ||
                        heads_[i]->timestamp_ns < heads_[best]->timestamp_ns)) {
        best = i;
      }
    }
    if (best == sources_.size()) return false;
    out = std::move(*heads_[best]);
    heads_[best].reset();
    return true;
  }

 private:
  void OpenDirectory(const std::string& dir) {
    const fs::path meta = fs::path(dir) / "metadata.yaml";
    if (!detail::IsRegularFile(meta.string())) {
      throw BagError("bag directory '" + dir + "' has no metadata.yaml");
    }
    YAML::Node root;
    try {
      root = YAML::LoadFile(meta.string());
    } catch (const YAML::Exception& e) {
      throw BagError("cannot parse '" + meta.string() + "': " + e.what());
    }
    const YAML::Node bag = root["rosbag2_bagfile_information"];
    if (!bag || !bag.IsMap()) {
      throw BagError("'" + meta.string() + "' has no rosbag2_bagfile_information map");
    }
    try {
      const std::string id = bag["storage_identifier"].as<std::string>("");
      Storage kind;
      if (id == "sqlite3") {
        kind = Storage::kSqlite3;
      } else if (id == "mcap") {
        kind = Storage::kMcap;
      } else if (id == StorageIdentifier(Storage::kRos1)) {
        kind = Storage::kRos1;
      } else {
        throw BagError("'" + meta.string() + "': unsupported storage_identifier '" + id + "'");
      }
      info_.storage = kind;
      const std::string comp = bag["compression_format"].as<std::string>("");
      if (!comp.empty()) {
        throw BagError("'" + meta.string() + "': file-level compression '" + comp +
                       "' is not supported");
      }
      const YAML::Node files = bag["relative_file_paths"];
      if (!files || !files.IsSequence() || files.size() == 0) {
        throw BagError("'" + meta.string() + "' lists no relative_file_paths");
      }
      for (const auto& f : files) {
        const std::string rel = f.as<std::string>();
        const fs::path p = fs::path(dir) / rel;
        if (!detail::IsRegularFile(p.string())) {
          throw BagError("'" + meta.string() + "' lists '" + rel + "' which does not exist");
        }
        sources_.push_back(OpenFile(p.string(), kind));
      }
    } catch (const YAML::Exception& e) {
      throw BagError("malformed '" + meta.string() + "': " + e.what());
    }
  }

  void MergeInfo() {
    std::map<std::string, size_t> index;
    bool any = false;
    for (const auto& s : sources_) {
      const BagInfo& fi = s->Info();
      for (const auto& t : fi.topics) {
        auto it = index.find(t.info.name);
        if (it == index.end()) {
          index[t.info.name] = info_.topics.size();
          info_.topics.push_back(t);
        } else {
          if (info_.topics[it->second].info.type != t.info.type) {
            throw BagError("topic '" + t.info.name + "' has different types across bag files");
          }
          info_.topics[it->second].message_count += t.message_count;
        }
      }
      if (fi.message_count) {
        if (!any || fi.start_ns < info_.start_ns) info_.start_ns = fi.start_ns;
        if (!any || fi.end_ns > info_.end_ns) info_.end_ns = fi.end_ns;
        any = true;
      }
      info_.message_count += fi.message_count;
    }
  }

  BagInfo info_;
  std::vector<std::unique_ptr<detail::StorageReader>> sources_;
  std::vector<std::optional<Message>> heads_;
  std::vector<bool> exhausted_;
  int64_t seek_ = std::numeric_limits<int64_t>::min();
};

Reader::Reader(const std::string& path) : impl_(std::make_unique<Impl>(path)) {
  impl_->Seek(std::numeric_limits<int64_t>::min());
}
Reader::~Reader() = default;
const BagInfo& Reader::Info() const { return impl_->Info(); }
void Reader::SetTopicFilter(std::vector<std::string> topics) {
  impl_->SetTopicFilter(std::move(topics));
}
bool Reader::Next(Message& out) { return impl_->Next(out); }
void Reader::Seek(int64_t t) { impl_->Seek(t); }

BagInfo ReadInfo(const std::string& path) { return Reader(path).Info(); }

}  // namespace ppf::bag
