#include "file_io.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "ppf_bag/bag.hpp"

namespace ppf::bag::detail {

InputFile::InputFile(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) throw BagError("cannot open '" + path + "': " + std::strerror(errno));
  struct stat st;
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd_);
    throw BagError("'" + path + "' is not a regular file");
  }
  size_ = static_cast<uint64_t>(st.st_size);
}

InputFile::~InputFile() {
  if (fd_ >= 0) ::close(fd_);
}

void InputFile::ReadAt(uint64_t offset, void* dst, size_t n) const {
  if (offset > size_ || n > size_ - offset) {
    throw BagError("'" + path_ + "' is truncated: need bytes [" + std::to_string(offset) + ", " +
                   std::to_string(offset + n) + ") but the file has " + std::to_string(size_));
  }
  auto* out = static_cast<uint8_t*>(dst);
  while (n > 0) {
    const ssize_t got = ::pread(fd_, out, n, static_cast<off_t>(offset));
    if (got < 0) {
      if (errno == EINTR) continue;
      throw BagError("read error in '" + path_ + "': " + std::strerror(errno));
    }
    if (got == 0) throw BagError("'" + path_ + "' is truncated (unexpected end of file)");
    out += got;
    offset += static_cast<uint64_t>(got);
    n -= static_cast<size_t>(got);
  }
}

std::vector<uint8_t> InputFile::ReadAt(uint64_t offset, size_t n) const {
  if (offset > size_ || n > size_ - offset) {
    // Check before allocating: a corrupt length field must not trigger a huge allocation.
    ReadAt(offset, nullptr, n);
  }
  std::vector<uint8_t> v(n);
  ReadAt(offset, v.data(), n);
  return v;
}

bool IsDirectory(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool IsRegularFile(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

}  // namespace ppf::bag::detail
