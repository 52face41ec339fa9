// ROS 1 bag reader (format 2.0, the only one rosbag has written since ROS Groovy).
//
// Layout: "#ROSBAG V2.0\n", a bag header record (padded to 4 KiB) holding index_pos, then chunk
// records (each followed by index data records), then at index_pos the connection records and
// one chunk info record per chunk. Every record is <uint32 header_len><header><uint32
// data_len><data>; a header is a list of <uint32 len>name=value fields, "op" giving the kind.
//
// Open reads only the bag header and the index section (connections, chunk infos): counts and
// times come from there. Iteration inflates chunks lazily in start-time order and merges their
// messages through a heap, so chunks with overlapping times still come out in timestamp order
// with bounded memory (as the MCAP reader does). Messages are converted to ROS 2 CDR when they
// are returned (ros1_convert.hpp). ROS 1 bags carry no checksums: damage is caught by the
// structural checks (lengths, op codes, ids, counts against the index), each naming the byte
// offset in the file (and inside the uncompressed chunk, for records in a chunk).
#include <algorithm>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <queue>
#include <unordered_map>

#include "compression.hpp"
#include "file_io.hpp"
#include "ros1_convert.hpp"
#include "ros1_format.hpp"
#include "storage.hpp"

namespace ppf::bag::detail {
namespace {

using ros1::BufRecord;
using ros1::Bz2Decompress;
using ros1::FieldAs;
using ros1::Fields;
using ros1::FieldStr;
using ros1::kBagHeader;
using ros1::kChunk;
using ros1::kChunkInfo;
using ros1::kConnection;
using ros1::kMagic;
using ros1::kMagicSize;
using ros1::kMaxHeaderLen;
using ros1::kMessageData;
using ros1::OpName;
using ros1::ParseBufRecord;
using ros1::ParseFields;
using ros1::TimeField;

// LZ4 never expands by more than 255:1 (a match is at most 255 bytes per length byte), so a
// declared size beyond that is a corrupt field; checked before the decompressor allocates it.
constexpr uint64_t kLz4MaxRatio = 256;

struct Connection {
  uint32_t id = 0;
  std::string topic, type, md5sum;
  Ros1Conversion conversion = Ros1Conversion::kPassThrough;
  uint64_t record_offset = 0;
};

struct ChunkRef {
  uint64_t offset = 0;  // of the chunk record in the file
  uint64_t start = 0, end = 0;
  std::map<uint32_t, uint32_t> counts;  // connection id -> messages in this chunk
  uint64_t info_offset = 0;             // of the chunk info record, for error messages
};

struct Pending {
  uint64_t time;
  uint64_t seq;  // storage order, for stable ties
  uint32_t conn;
  std::shared_ptr<const std::vector<uint8_t>> buf;
  size_t off, size;
  uint64_t chunk_offset;
  size_t record_pos;  // inside the inflated chunk
};

struct PendingLater {
  bool operator()(const Pending& a, const Pending& b) const {
    return a.time != b.time ? a.time > b.time : a.seq > b.seq;
  }
};

class Ros1Reader final : public StorageReader {
 public:
  explicit Ros1Reader(const std::string& path) : file_(path) {
    info_.storage = Storage::kRos1;
    const std::string& p = file_.path();
    if (file_.size() < kMagicSize) throw BagError("'" + p + "' is too short to be a ROS 1 bag");
    char magic[kMagicSize];
    file_.ReadAt(0, magic, kMagicSize);
    if (std::memcmp(magic, kMagic, kMagicSize) != 0) {
      if (std::memcmp(magic, "#ROSBAG V", 9) == 0) {
        throw BagError("'" + p + "' is a ROS 1 bag of format " +
                       std::string(magic + 9, magic + 12) + "; only 2.0 is supported");
      }
      throw BagError("'" + p + "' is not a ROS 1 bag (no '#ROSBAG V2.0' line at byte 0)");
    }
    const Fields bh = ReadRecordHeader(kMagicSize, nullptr, nullptr);
    const std::string bh_where = Where(kMagicSize);
    if (FieldAs<uint8_t>(bh, "op", bh_where) != kBagHeader) {
      throw BagError(bh_where + ": expected the bag header record (op 0x03)");
    }
    const uint64_t index_pos = FieldAs<uint64_t>(bh, "index_pos", bh_where);
    const uint32_t conn_count = FieldAs<uint32_t>(bh, "conn_count", bh_where);
    const uint32_t chunk_count = FieldAs<uint32_t>(bh, "chunk_count", bh_where);
    if (index_pos == 0) {
      throw BagError(bh_where +
                     ": the bag is not indexed (index_pos 0: recording was "
                     "interrupted?); run `rosbag reindex` on it first");
    }
    if (index_pos <= kMagicSize || index_pos > file_.size()) {
      throw BagError(bh_where + ": index_pos " + std::to_string(index_pos) +
                     " lies outside the file of " + std::to_string(file_.size()) +
                     " bytes (truncated?)");
    }
    ReadIndex(index_pos, conn_count, chunk_count);
    std::stable_sort(chunks_.begin(), chunks_.end(),
                     [](const ChunkRef& a, const ChunkRef& b) { return a.start < b.start; });
    Seek(std::numeric_limits<int64_t>::min());
  }

  const BagInfo& Info() const override { return info_; }

  void SetFilter(const std::unordered_set<std::string>& topics) override { filter_ = topics; }

  void Seek(int64_t timestamp_ns) override {
    seek_time_ = timestamp_ns < 0 ? 0 : static_cast<uint64_t>(timestamp_ns);
    heap_ = {};
    cursor_ = 0;
  }

  bool Next(Message& out) override {
    while (cursor_ < chunks_.size() &&
           (heap_.empty() || chunks_[cursor_].start <= heap_.top().time)) {
      LoadChunk(chunks_[cursor_++]);
    }
    if (heap_.empty()) return false;
    Pending m = heap_.top();
    heap_.pop();
    const Connection& c = connections_.at(m.conn);
    std::string error;
    if (!ConvertRos1Message(c.conversion, m.buf->data() + m.off, m.size, &out.data, &error)) {
      throw BagError(Where(m.chunk_offset) + ", message record at byte " +
                     std::to_string(m.record_pos) + " of the inflated chunk: " + c.type + " on '" +
                     c.topic + "' is malformed: " + error);
    }
    out.topic = c.topic;
    out.timestamp_ns = static_cast<int64_t>(m.time);
    return true;
  }

 private:
  std::string Where(uint64_t offset) const {
    return "'" + file_.path() + "': record at byte offset " + std::to_string(offset);
  }

  // Reads the header of the record at `pos`; returns its fields, and (if asked) where its data
  // starts and how long it is. Lengths are checked against the file before anything is read.
  Fields ReadRecordHeader(uint64_t pos, uint64_t* data_pos, uint32_t* data_len) const {
    const std::string where = Where(pos);
    uint32_t hlen;
    if (pos > file_.size() || file_.size() - pos < 4) {
      throw BagError(where + ": file ends inside the record's header length (truncated)");
    }
    file_.ReadAt(pos, &hlen, 4);
    if (hlen > kMaxHeaderLen || hlen > file_.size() - pos - 4) {
      throw BagError(where + ": header length " + std::to_string(hlen) +
                     " runs past the end of the file (truncated or corrupt)");
    }
    const auto h = file_.ReadAt(pos + 4, hlen);
    Fields f = ParseFields(h.data(), h.size(), where);
    const uint64_t dl_pos = pos + 4 + hlen;
    if (file_.size() - dl_pos < 4) {
      throw BagError(where + ": file ends inside the record's data length (truncated)");
    }
    uint32_t dlen;
    file_.ReadAt(dl_pos, &dlen, 4);
    if (dlen > file_.size() - dl_pos - 4) {
      throw BagError(where + ": data of " + std::to_string(dlen) +
                     " bytes runs past the end of the file (truncated or corrupt)");
    }
    if (data_pos) *data_pos = dl_pos + 4;
    if (data_len) *data_len = dlen;
    return f;
  }

  void ReadIndex(uint64_t index_pos, uint32_t conn_count, uint32_t chunk_count) {
    uint64_t pos = index_pos;
    while (pos < file_.size()) {
      uint64_t data_pos;
      uint32_t data_len;
      const Fields h = ReadRecordHeader(pos, &data_pos, &data_len);
      const std::string where = Where(pos);
      const uint8_t op = FieldAs<uint8_t>(h, "op", where);
      const auto data = file_.ReadAt(data_pos, data_len);
      if (op == kConnection) {
        AddConnection(h, data, pos, where);
      } else if (op == kChunkInfo) {
        AddChunkInfo(h, data, pos, index_pos, where);
      } else {
        throw BagError(where + ": unexpected record op " + OpName(op) +
                       " in the index section (expected connection 0x07 or chunk info 0x06)");
      }
      pos = data_pos + data_len;
    }
    if (connections_.size() != conn_count || chunks_.size() != chunk_count) {
      throw BagError(Where(kMagicSize) + ": bag header announces " + std::to_string(conn_count) +
                     " connections and " + std::to_string(chunk_count) +
                     " chunks, the index section at byte offset " + std::to_string(index_pos) +
                     " holds " + std::to_string(connections_.size()) + " and " +
                     std::to_string(chunks_.size()) + " (truncated?)");
    }
    // Counts and times from the chunk infos; topics in connection order.
    std::map<std::string, size_t> topic_index;
    std::map<uint32_t, uint64_t> per_conn;
    for (const ChunkRef& c : chunks_) {
      for (const auto& [id, n] : c.counts) {
        if (!connections_.count(id)) {
          throw BagError(Where(c.info_offset) + ": chunk info counts messages of connection " +
                         std::to_string(id) + " which the bag does not define");
        }
        per_conn[id] += n;
        info_.message_count += n;
      }
      if (!c.counts.empty()) {
        if (!any_time_ || c.start < start_) start_ = c.start;
        if (!any_time_ || c.end > end_) end_ = c.end;
        any_time_ = true;
      }
    }
    for (uint32_t id : connection_order_) {
      const Connection& c = connections_.at(id);
      const std::string type = Ros1PresentedType(c.conversion, c.type);
      auto it = topic_index.find(c.topic);
      if (it == topic_index.end()) {
        topic_index[c.topic] = info_.topics.size();
        TopicStats ts;
        ts.info.name = c.topic;
        ts.info.type = type;
        ts.info.serialization_format =
            c.conversion == Ros1Conversion::kPassThrough ? "ros1" : "cdr";
        ts.message_count = per_conn[id];
        info_.topics.push_back(ts);
      } else {
        TopicStats& ts = info_.topics[it->second];
        if (ts.info.type != type) {
          throw BagError(Where(c.record_offset) + ": topic '" + c.topic +
                         "' has connections of "
                         "different types ('" +
                         ts.info.type + "' and '" + type + "')");
        }
        ts.message_count += per_conn[id];
      }
    }
    if (any_time_ && info_.message_count) {
      info_.start_ns = static_cast<int64_t>(start_);
      info_.end_ns = static_cast<int64_t>(end_);
    }
  }

  void AddConnection(const Fields& h, const std::vector<uint8_t>& data, uint64_t pos,
                     const std::string& where) {
    Connection c;
    c.id = FieldAs<uint32_t>(h, "conn", where);
    c.topic = FieldStr(h, "topic", where);
    c.record_offset = pos;
    // The data is the connection header the publisher sent: type, md5sum, definition, ...
    const Fields d = ParseFields(data.data(), data.size(), where + " (connection header)");
    c.type = FieldStr(d, "type", where + " (connection header)");
    c.md5sum = FieldStr(d, "md5sum", where + " (connection header)");
    c.conversion = Ros1ConversionFor(c.type, c.md5sum);
    if (c.topic.empty())
      throw BagError(where + ": connection " + std::to_string(c.id) + " has an empty topic");
    if (connections_.count(c.id)) {
      throw BagError(where + ": connection id " + std::to_string(c.id) + " defined twice");
    }
    connection_order_.push_back(c.id);
    connections_[c.id] = std::move(c);
  }

  void AddChunkInfo(const Fields& h, const std::vector<uint8_t>& data, uint64_t pos,
                    uint64_t index_pos, const std::string& where) {
    if (FieldAs<uint32_t>(h, "ver", where) != 1) {
      throw BagError(where + ": chunk info version is not 1");
    }
    ChunkRef c;
    c.info_offset = pos;
    c.offset = FieldAs<uint64_t>(h, "chunk_pos", where);
    c.start = TimeField(h, "start_time", where);
    c.end = TimeField(h, "end_time", where);
    const uint32_t count = FieldAs<uint32_t>(h, "count", where);
    if (c.offset < kMagicSize || c.offset >= index_pos) {
      throw BagError(where + ": chunk_pos " + std::to_string(c.offset) +
                     " is not inside the data section [" + std::to_string(kMagicSize) + ", " +
                     std::to_string(index_pos) + ")");
    }
    if (data.size() != uint64_t(count) * 8) {
      throw BagError(where + ": chunk info lists " + std::to_string(count) + " connections in " +
                     std::to_string(data.size()) + " bytes (expected " +
                     std::to_string(uint64_t(count) * 8) + ")");
    }
    for (uint32_t i = 0; i < count; ++i) {
      uint32_t id, n;
      std::memcpy(&id, data.data() + 8 * i, 4);
      std::memcpy(&n, data.data() + 8 * i + 4, 4);
      c.counts[id] += n;
    }
    chunks_.push_back(std::move(c));
  }

  bool Wanted(uint32_t conn) const {
    return filter_.empty() || filter_.count(connections_.at(conn).topic) > 0;
  }

  // The chunk record at ref.offset, decompressed and checked against its declared size.
  std::shared_ptr<const std::vector<uint8_t>> InflateChunk(const ChunkRef& ref,
                                                           const std::string& where) {
    uint64_t data_pos;
    uint32_t data_len;
    const Fields h = ReadRecordHeader(ref.offset, &data_pos, &data_len);
    if (FieldAs<uint8_t>(h, "op", where) != kChunk) {
      throw BagError(where + ": chunk info (at byte offset " + std::to_string(ref.info_offset) +
                     ") points here but this is not a chunk record");
    }
    const std::string& compression = FieldStr(h, "compression", where);
    const uint32_t size = FieldAs<uint32_t>(h, "size", where);
    const auto raw = file_.ReadAt(data_pos, data_len);
    std::shared_ptr<const std::vector<uint8_t>> buf;
    try {
      if (compression == "none") {
        if (raw.size() != size) {
          throw BagError("uncompressed chunk has " + std::to_string(raw.size()) +
                         " bytes but declares " + std::to_string(size));
        }
        buf = std::make_shared<std::vector<uint8_t>>(raw);
      } else if (compression == "bz2") {
        buf = std::make_shared<std::vector<uint8_t>>(Bz2Decompress(raw, size, where));
      } else if (compression == "lz4") {
        if (size > raw.size() * kLz4MaxRatio + 1024) {
          throw BagError("lz4 chunk of " + std::to_string(raw.size()) + " bytes declares " +
                         std::to_string(size) + " uncompressed bytes, beyond lz4's ratio");
        }
        buf =
            std::make_shared<std::vector<uint8_t>>(Decompress("lz4", raw.data(), raw.size(), size));
      } else {
        throw BagError("unknown chunk compression '" + compression + "'");
      }
    } catch (const BagError& e) {
      const std::string what = e.what();
      if (what.find(where) != std::string::npos) throw;
      throw BagError(where + ": " + what.substr(std::strlen("ppf_bag: ")));
    }
    return buf;
  }

  void LoadChunk(const ChunkRef& ref) {
    // Skip chunks that cannot contribute: before the seek time, or only filtered-out topics.
    if (ref.end < seek_time_) return;
    bool any = false;
    for (const auto& [id, n] : ref.counts) any = any || (n > 0 && Wanted(id));
    if (!any) return;

    const std::string where = Where(ref.offset);
    const std::shared_ptr<const std::vector<uint8_t>> buf = InflateChunk(ref, where);
    std::map<uint32_t, uint32_t> seen;
    size_t pos = 0;
    while (pos < buf->size()) {
      const std::string rwhere =
          where + ", record at byte " + std::to_string(pos) + " of the inflated chunk";
      const BufRecord r = ParseBufRecord(*buf, pos, rwhere);
      const uint8_t op = FieldAs<uint8_t>(r.header, "op", rwhere);
      if (op == kMessageData) {
        const uint32_t conn = FieldAs<uint32_t>(r.header, "conn", rwhere);
        if (!connections_.count(conn)) {
          throw BagError(rwhere + ": message on connection " + std::to_string(conn) +
                         " which the bag does not define");
        }
        ++seen[conn];
        const uint64_t t = TimeField(r.header, "time", rwhere);
        if (t >= seek_time_ && Wanted(conn)) {
          heap_.push(Pending{t, seq_++, conn, buf, r.data_pos, r.data_len, ref.offset, pos});
        }
      } else if (op == kConnection) {
        const uint32_t conn = FieldAs<uint32_t>(r.header, "conn", rwhere);
        if (!connections_.count(conn)) {
          throw BagError(rwhere + ": connection " + std::to_string(conn) +
                         " is missing from the bag's index");
        }
      } else {
        throw BagError(rwhere + ": unexpected record op " + OpName(op) +
                       " inside a chunk (expected message 0x02 or connection 0x07)");
      }
      pos = r.end;
    }
    // The index and the chunk must agree; a mismatch means one of them is damaged.
    std::map<uint32_t, uint32_t> expected;
    for (const auto& [id, n] : ref.counts) {
      if (n) expected[id] = n;
    }
    if (seen != expected) {
      throw BagError(where +
                     ": the chunk holds a different number of messages per connection "
                     "than its chunk info at byte offset " +
                     std::to_string(ref.info_offset) + " says (damaged chunk or index)");
    }
  }

  InputFile file_;
  BagInfo info_;
  std::unordered_map<uint32_t, Connection> connections_;
  std::vector<uint32_t> connection_order_;
  std::vector<ChunkRef> chunks_;
  bool any_time_ = false;
  uint64_t start_ = 0, end_ = 0;

  std::unordered_set<std::string> filter_;
  uint64_t seek_time_ = 0;
  size_t cursor_ = 0;
  uint64_t seq_ = 0;
  std::priority_queue<Pending, std::vector<Pending>, PendingLater> heap_;
};

}  // namespace

std::unique_ptr<StorageReader> OpenRos1(const std::string& path) {
  return std::make_unique<Ros1Reader>(path);
}

}  // namespace ppf::bag::detail
