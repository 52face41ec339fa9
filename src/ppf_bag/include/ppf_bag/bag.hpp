// rosbag2-compatible bag storage: sqlite3 (.db3, Humble/Jazzy/older) and MCAP (ros2 profile),
// plus reading ROS 1 bags (.bag, format 2.0).
//
// A bag is a directory holding metadata.yaml plus one or more storage files, exactly as
// `ros2 bag record` produces it. Readers also accept a single .db3, .mcap or .bag file.
// A ROS 1 bag is read-only. Its sensor_msgs/PointCloud2 and sensor_msgs/Imu messages (and Livox
// CustomMsg clouds, as PointCloud2) are returned converted to ROS 2 CDR under their ROS 2 type
// names ("sensor_msgs/msg/Imu", serialization_format "cdr"), so every consumer reads them as it
// reads a rosbag2 bag; any other type keeps its ROS 1 name ("tf2_msgs/TFMessage") and its ROS 1
// bytes, with serialization_format "ros1", which consumers that want CDR must skip.
// Writer and Reader objects are not thread-safe: serialize calls on one object (separate objects
// are independent).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace ppf::bag {

// Every failure (missing file, bad schema, truncated/corrupt record, CRC mismatch, misuse)
// is reported with this exception; nothing is skipped silently.
class BagError : public std::runtime_error {
 public:
  explicit BagError(const std::string& what) : std::runtime_error("ppf_bag: " + what) {}
};

enum class Storage { kSqlite3, kMcap, kRos1 };

// "sqlite3" / "mcap", as rosbag2 writes storage_identifier; "rosbag_v2" for a ROS 1 bag (the
// identifier of rosbag2's ROS 1 bag plugin).
const char* StorageIdentifier(Storage storage);

struct TopicInfo {
  std::string name;                         // "/imu"
  std::string type;                         // "sensor_msgs/msg/Imu"
  std::string serialization_format = "cdr";
  std::string offered_qos_profiles;         // YAML text as rosbag2 stores it, may be empty
};

struct Message {
  std::string topic;
  int64_t timestamp_ns = 0;   // receive (log) time
  std::vector<uint8_t> data;  // whole CDR payload incl. 4-byte encapsulation header
};

struct TopicStats {
  TopicInfo info;
  uint64_t message_count = 0;
};

struct BagInfo {
  Storage storage = Storage::kMcap;
  int64_t start_ns = 0;  // earliest message timestamp (0 if the bag is empty)
  int64_t end_ns = 0;    // latest message timestamp (0 if the bag is empty)
  uint64_t message_count = 0;
  std::vector<TopicStats> topics;  // in topic registration order

  int64_t duration_ns() const { return end_ns - start_ns; }
};

struct WriterOptions {
  Storage storage = Storage::kMcap;
  std::string compression = "none";  // mcap: none|lz4|zstd chunk compression; sqlite3: none only
  size_t chunk_size = 4 << 20;       // mcap: uncompressed chunk size before it is flushed
};

class Writer {
 public:
  // Creates directory `dir` (must not exist yet, or be empty) and the storage file
  // `<basename(dir)>_0.db3|.mcap` inside it.
  Writer(const std::string& dir, const WriterOptions& options = WriterOptions());
  ~Writer();  // closes; errors during an implicit close are swallowed, call Close() to see them
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // Registers a topic. Re-adding an identical topic is a no-op; a different type for the same
  // name throws. For MCAP the schema text comes from MessageDefinition(info.type).
  void AddTopic(const TopicInfo& info);
  // Topic must have been added. Data is the whole CDR payload.
  void Write(const std::string& topic, int64_t timestamp_ns, const uint8_t* data, size_t size);
  void Write(const std::string& topic, int64_t timestamp_ns, const std::vector<uint8_t>& data) {
    Write(topic, timestamp_ns, data.data(), data.size());
  }
  // Finishes the storage file and writes metadata.yaml. Idempotent.
  void Close();

  const std::string& storage_file() const;  // full path of the storage file

  class Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

class Reader {
 public:
  // A directory with metadata.yaml, or a single .db3 / .mcap / .bag (ROS 1) file.
  explicit Reader(const std::string& dir_or_file);
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  const BagInfo& Info() const;
  // Only messages on these topics are returned by Next(); empty = all topics. Unknown topic
  // names throw. Rewinds to the last Seek() position (the start of the bag if never sought).
  void SetTopicFilter(std::vector<std::string> topics);
  // Next message in timestamp order across all topics and files (ties: storage order).
  // Returns false at the end of the bag.
  bool Next(Message& out);
  // Positions so that the next message returned is the first with timestamp >= timestamp_ns.
  void Seek(int64_t timestamp_ns);

  class Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// ros2msg text for MCAP schemas: the .msg definition of `type` ("pkg/msg/Type") with all nested
// dependencies appended after a line of 80 '=' and "MSG: pkg/Type", as rosbag2 writes it.
// Unknown type (or a type with an unknown dependency) -> empty string.
std::string MessageDefinition(const std::string& type);

// Convenience: Reader(dir_or_file).Info().
BagInfo ReadInfo(const std::string& dir_or_file);

}  // namespace ppf::bag
