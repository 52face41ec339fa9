// Positional read-only file access (pread), so readers never depend on a shared file cursor.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ppf::bag::detail {

class InputFile {
 public:
  explicit InputFile(const std::string& path);  // throws BagError if missing/unreadable
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  uint64_t size() const { return size_; }
  const std::string& path() const { return path_; }
  // Reads exactly n bytes at offset or throws BagError ("truncated").
  void ReadAt(uint64_t offset, void* dst, size_t n) const;
  std::vector<uint8_t> ReadAt(uint64_t offset, size_t n) const;

 private:
  std::string path_;
  int fd_ = -1;
  uint64_t size_ = 0;
};

bool IsDirectory(const std::string& path);
bool IsRegularFile(const std::string& path);

}  // namespace ppf::bag::detail
