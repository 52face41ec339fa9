// Internal interfaces between the public Reader/Writer and the storage backends.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_set>
#include <vector>

#include "ppf_bag/bag.hpp"

namespace ppf::bag::detail {

class StorageWriter {
 public:
  virtual ~StorageWriter() = default;
  virtual void AddTopic(const TopicInfo& info) = 0;
  virtual void Write(const TopicInfo& topic, int64_t timestamp_ns, const uint8_t* data,
                     size_t size) = 0;
  virtual void Close() = 0;
};

// One storage file, iterated in timestamp order (ties: storage order).
class StorageReader {
 public:
  virtual ~StorageReader() = default;
  // Topics with counts, and first/last timestamps of the file (0/0 if empty).
  virtual const BagInfo& Info() const = 0;
  // Empty set = all topics. Applies from the next Seek().
  virtual void SetFilter(const std::unordered_set<std::string>& topics) = 0;
  // Restart iteration at the first message with timestamp >= t.
  virtual void Seek(int64_t timestamp_ns) = 0;
  virtual bool Next(Message& out) = 0;
};

std::unique_ptr<StorageWriter> MakeSqliteWriter(const std::string& path);
std::unique_ptr<StorageWriter> MakeMcapWriter(const std::string& path, const WriterOptions& options);
std::unique_ptr<StorageReader> OpenSqlite(const std::string& path);
std::unique_ptr<StorageReader> OpenMcap(const std::string& path);
std::unique_ptr<StorageReader> OpenRos1(const std::string& path);

}  // namespace ppf::bag::detail
