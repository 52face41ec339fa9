// MCAP writer (ros2 profile): Schema/Channel records in the data section, messages in chunks
// followed by their MessageIndex records, then a summary section with Schema, Channel,
// Statistics and ChunkIndex groups, SummaryOffset records and a Footer carrying the summary CRC.
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>

#include "compression.hpp"
#include "crc32.hpp"
#include "mcap_format.hpp"
#include "storage.hpp"

namespace ppf::bag::detail {
namespace {

using mcap::Builder;

struct ChannelState {
  uint16_t id = 0;
  uint16_t schema_id = 0;
  TopicInfo info;
  uint32_t sequence = 0;
  uint64_t count = 0;
};

struct ChunkIndexEntry {
  uint64_t start = 0, end = 0, offset = 0, length = 0;
  std::map<uint16_t, uint64_t> index_offsets;
  uint64_t index_length = 0;
  std::string compression;
  uint64_t compressed_size = 0, uncompressed_size = 0;
};

class McapWriter final : public StorageWriter {
 public:
  McapWriter(const std::string& path, const WriterOptions& options)
      : path_(path),
        compression_(options.compression == "none" ? "" : options.compression),
        chunk_size_(options.chunk_size) {
    if (!IsSupportedCompression(compression_)) {
      throw BagError("unsupported MCAP compression '" + options.compression +
                     "' (expected none, lz4 or zstd)");
    }
    file_ = std::fopen(path.c_str(), "wb");
    if (!file_) throw BagError("cannot create '" + path + "': " + std::strerror(errno));
    Builder b;
    b.Bytes(mcap::kMagic, sizeof(mcap::kMagic));
    const size_t at = b.BeginRecord(mcap::kHeader);
    b.Str("ros2");
    b.Str("ppf_bag 0.1.0");
    b.EndRecord(at);
    Emit(b.buf, true);
  }

  ~McapWriter() override {
    if (file_) std::fclose(file_);
  }

  void AddTopic(const TopicInfo& info) override {
    if (channels_.count(info.name)) return;
    if (channels_.size() >= std::numeric_limits<uint16_t>::max()) {
      throw BagError("too many topics for one MCAP file");
    }
    uint16_t schema_id;
    auto it = schema_ids_.find(info.type);
    Builder b;
    if (it == schema_ids_.end()) {
      schema_id = static_cast<uint16_t>(schemas_.size() + 1);
      schema_ids_[info.type] = schema_id;
      const std::string def = MessageDefinition(info.type);
      Builder s;
      const size_t at = s.BeginRecord(mcap::kSchema);
      s.U16(schema_id);
      s.Str(info.type);
      s.Str(def.empty() ? "" : "ros2msg");
      s.Str(def);
      s.EndRecord(at);
      schemas_.push_back(s.buf);
      b.Bytes(s.buf.data(), s.buf.size());
    } else {
      schema_id = it->second;
    }
    ChannelState ch;
    ch.id = static_cast<uint16_t>(channel_order_.size() + 1);
    ch.schema_id = schema_id;
    ch.info = info;
    Builder c;
    const size_t at = c.BeginRecord(mcap::kChannel);
    c.U16(ch.id);
    c.U16(schema_id);
    c.Str(info.name);
    c.Str(info.serialization_format);
    const size_t map_at = c.Begin32();
    c.Str("offered_qos_profiles");
    c.Str(info.offered_qos_profiles);
    c.End32(map_at);
    c.EndRecord(at);
    channel_records_.push_back(c.buf);
    b.Bytes(c.buf.data(), c.buf.size());
    // Written before the pending chunk, so readers meet the channel before its messages.
    Emit(b.buf, true);
    channel_order_.push_back(info.name);
    channels_[info.name] = ch;
  }

  void Write(const TopicInfo& topic, int64_t timestamp_ns, const uint8_t* data,
             size_t size) override {
    auto it = channels_.find(topic.name);
    if (it == channels_.end()) throw BagError("topic '" + topic.name + "' was not added");
    if (timestamp_ns < 0) {
      throw BagError("negative timestamp " + std::to_string(timestamp_ns) + " on '" + topic.name +
                     "' cannot be stored in MCAP");
    }
    ChannelState& ch = it->second;
    const uint64_t t = static_cast<uint64_t>(timestamp_ns);
    msg_index_[ch.id].emplace_back(t, chunk_.buf.size());
    const size_t at = chunk_.BeginRecord(mcap::kMessage);
    chunk_.U16(ch.id);
    chunk_.U32(ch.sequence++);
    chunk_.U64(t);
    chunk_.U64(t);
    chunk_.Bytes(data, size);
    chunk_.EndRecord(at);
    if (chunk_messages_ == 0 || t < chunk_start_) chunk_start_ = t;
    if (chunk_messages_ == 0 || t > chunk_end_) chunk_end_ = t;
    ++chunk_messages_;
    ++ch.count;
    if (message_count_ == 0 || t < start_) start_ = t;
    if (message_count_ == 0 || t > end_) end_ = t;
    ++message_count_;
    if (chunk_.buf.size() >= chunk_size_) FlushChunk();
  }

  void Close() override {
    if (!file_) return;
    FlushChunk();
    WriteDataEnd();
    // The summary section: schemas, channels, statistics and chunk indexes, each group located
    // by a SummaryOffset record, then the footer.
    const uint64_t summary_start = offset_;
    Builder s;
    struct Group {
      uint8_t op;
      uint64_t start, length;
    };
    std::vector<Group> groups;
    auto group = [&](uint8_t op, auto&& body) {
      const size_t begin = s.buf.size();
      body();
      if (s.buf.size() > begin) groups.push_back({op, summary_start + begin, s.buf.size() - begin});
    };
    group(mcap::kSchema, [&] {
      for (const auto& r : schemas_) s.Bytes(r.data(), r.size());
    });
    group(mcap::kChannel, [&] {
      for (const auto& r : channel_records_) s.Bytes(r.data(), r.size());
    });
    group(mcap::kStatistics, [&] { AppendStatistics(&s); });
    group(mcap::kChunkIndex, [&] { AppendChunkIndexes(&s); });
    const uint64_t summary_offset_start = summary_start + s.buf.size();
    for (const auto& g : groups) {
      const size_t at = s.BeginRecord(mcap::kSummaryOffset);
      s.U8(g.op);
      s.U64(g.start);
      s.U64(g.length);
      s.EndRecord(at);
    }
    // Length written up front: the summary CRC covers the footer's opcode and length too.
    s.U8(mcap::kFooter);
    s.U64(mcap::kFooterContent);
    s.U64(summary_start);
    s.U64(summary_offset_start);
    const uint32_t summary_crc = Crc32(s.buf.data(), s.buf.size());
    s.U32(summary_crc);
    s.Bytes(mcap::kMagic, sizeof(mcap::kMagic));
    Emit(s.buf, false);
    const bool flush_failed = std::fflush(file_) != 0;
    const bool close_failed = std::fclose(file_) != 0;
    file_ = nullptr;
    if (flush_failed || close_failed) throw BagError("error while finishing '" + path_ + "'");
  }

 private:
  // DataEnd carries the CRC of the data section; its own bytes are not part of it.
  void WriteDataEnd() {
    Builder b;
    const size_t at = b.BeginRecord(mcap::kDataEnd);
    b.U32(0);
    b.EndRecord(at);
    const uint32_t data_crc = crc_;
    b.buf[9] = data_crc & 0xFF;
    b.buf[10] = (data_crc >> 8) & 0xFF;
    b.buf[11] = (data_crc >> 16) & 0xFF;
    b.buf[12] = (data_crc >> 24) & 0xFF;
    Emit(b.buf, false);
  }

  void AppendStatistics(Builder* s) {
    const size_t at = s->BeginRecord(mcap::kStatistics);
    s->U64(message_count_);
    s->U16(static_cast<uint16_t>(schemas_.size()));
    s->U32(static_cast<uint32_t>(channels_.size()));
    s->U32(0);  // attachments
    s->U32(0);  // metadata
    s->U32(static_cast<uint32_t>(chunk_indexes_.size()));
    s->U64(message_count_ ? start_ : 0);
    s->U64(message_count_ ? end_ : 0);
    const size_t m = s->Begin32();
    for (const auto& name : channel_order_) {
      s->U16(channels_[name].id);
      s->U64(channels_[name].count);
    }
    s->End32(m);
    s->EndRecord(at);
  }

  void AppendChunkIndexes(Builder* s) const {
    for (const auto& ci : chunk_indexes_) {
      const size_t at = s->BeginRecord(mcap::kChunkIndex);
      s->U64(ci.start);
      s->U64(ci.end);
      s->U64(ci.offset);
      s->U64(ci.length);
      const size_t m = s->Begin32();
      for (const auto& [id, off] : ci.index_offsets) {
        s->U16(id);
        s->U64(off);
      }
      s->End32(m);
      s->U64(ci.index_length);
      s->Str(ci.compression);
      s->U64(ci.compressed_size);
      s->U64(ci.uncompressed_size);
      s->EndRecord(at);
    }
  }

  void Emit(const std::vector<uint8_t>& bytes, bool data_section) {
    if (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) {
      throw BagError("write to '" + path_ + "' failed: " + std::strerror(errno));
    }
    if (data_section) crc_ = Crc32Update(crc_, bytes.data(), bytes.size());
    offset_ += bytes.size();
  }

  void FlushChunk() {
    if (chunk_messages_ == 0) return;
    const std::vector<uint8_t>& raw = chunk_.buf;
    const std::vector<uint8_t> packed = Compress(compression_, raw.data(), raw.size());
    Builder b;
    size_t at = b.BeginRecord(mcap::kChunk);
    b.U64(chunk_start_);
    b.U64(chunk_end_);
    b.U64(raw.size());
    b.U32(Crc32(raw.data(), raw.size()));
    b.Str(compression_);
    b.U64(packed.size());
    b.Bytes(packed.data(), packed.size());
    b.EndRecord(at);
    ChunkIndexEntry ci;
    ci.start = chunk_start_;
    ci.end = chunk_end_;
    ci.offset = offset_;
    ci.length = b.buf.size();
    ci.compression = compression_;
    ci.compressed_size = packed.size();
    ci.uncompressed_size = raw.size();
    for (auto& [id, entries] : msg_index_) {
      if (entries.empty()) continue;
      ci.index_offsets[id] = offset_ + b.buf.size();
      // The spec wants index entries in log_time order; stable keeps write order for ties.
      std::stable_sort(entries.begin(), entries.end(),
                       [](const auto& a, const auto& c) { return a.first < c.first; });
      at = b.BeginRecord(mcap::kMessageIndex);
      b.U16(id);
      const size_t arr = b.Begin32();
      for (const auto& [t, off] : entries) {
        b.U64(t);
        b.U64(off);
      }
      b.End32(arr);
      b.EndRecord(at);
    }
    ci.index_length = offset_ + b.buf.size() - ci.offset - ci.length;
    Emit(b.buf, true);
    chunk_indexes_.push_back(std::move(ci));
    chunk_.buf.clear();
    msg_index_.clear();
    chunk_messages_ = 0;
  }

  std::string path_;
  std::string compression_;
  size_t chunk_size_;
  std::FILE* file_ = nullptr;
  uint64_t offset_ = 0;
  uint32_t crc_ = 0;

  std::map<std::string, uint16_t> schema_ids_;
  std::vector<std::vector<uint8_t>> schemas_;
  std::vector<std::vector<uint8_t>> channel_records_;
  std::map<std::string, ChannelState> channels_;
  std::vector<std::string> channel_order_;

  Builder chunk_;
  std::map<uint16_t, std::vector<std::pair<uint64_t, uint64_t>>> msg_index_;
  uint64_t chunk_start_ = 0, chunk_end_ = 0, chunk_messages_ = 0;
  std::vector<ChunkIndexEntry> chunk_indexes_;

  uint64_t message_count_ = 0, start_ = 0, end_ = 0;
};

}  // namespace

std::unique_ptr<StorageWriter> MakeMcapWriter(const std::string& path,
                                              const WriterOptions& options) {
  return std::make_unique<McapWriter>(path, options);
}

}  // namespace ppf::bag::detail
