// MCAP reader. Open: validates magic/footer, reads the summary (CRC-checked) and walks the data
// section once (CRC-checked against DataEnd) to locate chunks and loose messages. Counts come
// from the Statistics record; without one every chunk is inflated once to count.
// Iteration: chunks are inflated lazily in start-time order and their messages merged through a
// heap, so overlapping chunks still come out in timestamp order with bounded memory.
#include <algorithm>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <queue>
#include <unordered_map>

#include "compression.hpp"
#include "crc32.hpp"
#include "file_io.hpp"
#include "mcap_format.hpp"
#include "storage.hpp"

namespace ppf::bag::detail {
namespace {

using mcap::Parser;

struct SchemaRec {
  std::string name, encoding;
};

struct ChannelRec {
  uint16_t schema_id = 0;
  std::string topic, message_encoding;
  std::map<std::string, std::string> metadata;
};

// A chunk or a message stored outside chunks.
struct Unit {
  bool is_chunk = false;
  uint64_t offset = 0;  // of the record (opcode byte)
  uint64_t length = 0;  // whole record incl. prefix
  uint64_t start = 0, end = 0;
  uint64_t order = 0;  // file order, for stable ties
};

struct Pending {
  uint64_t time;
  uint64_t seq;
  uint16_t channel;
  std::shared_ptr<const std::vector<uint8_t>> buf;
  size_t off, size;
};

struct PendingLater {
  bool operator()(const Pending& a, const Pending& b) const {
    return a.time != b.time ? a.time > b.time : a.seq > b.seq;
  }
};

class McapReader final : public StorageReader {
 public:
  explicit McapReader(const std::string& path) : file_(path) {
    info_.storage = Storage::kMcap;
    const Footer footer = ReadFooter();
    if (footer.summary_crc != 0) CheckSummaryCrc(footer);
    const Statistics stats = ReadSummary(footer);
    ScanDataSection(footer.data_end_bound);
    // Statistics are trusted only if they cover every channel they count.
    bool stats_usable = stats.present && (stats.count == 0 || !stats.channel_counts.empty());
    for (const auto& [id, n] : stats.channel_counts) {
      if (!channels_.count(id)) stats_usable = false;
    }
    std::map<uint16_t, uint64_t> counts;
    if (stats_usable) {
      counts = stats.channel_counts;
      info_.message_count = stats.count;
      info_.start_ns = static_cast<int64_t>(stats.start);
      info_.end_ns = static_cast<int64_t>(stats.end);
    } else {
      CountByScanning(counts);
    }
    BuildTopics(counts);
    std::stable_sort(units_.begin(), units_.end(),
                     [](const Unit& a, const Unit& b) { return a.start < b.start; });
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
    for (;;) {
      while (cursor_ < units_.size() &&
             (heap_.empty() || units_[cursor_].start <= heap_.top().time)) {
        LoadUnit(units_[cursor_++]);
      }
      if (heap_.empty()) return false;
      Pending m = heap_.top();
      heap_.pop();
      out.topic = channels_.at(m.channel).topic;
      out.timestamp_ns = static_cast<int64_t>(m.time);
      out.data.assign(m.buf->data() + m.off, m.buf->data() + m.off + m.size);
      return true;
    }
  }

 private:
  struct Footer {
    uint64_t position = 0;  // of the Footer record
    uint64_t summary_start = 0;
    uint64_t summary_offset_start = 0;
    uint32_t summary_crc = 0;
    uint64_t data_end_bound = 0;  // the data section ends before this
  };

  struct Statistics {
    bool present = false;
    uint64_t count = 0, start = 0, end = 0;
    std::map<uint16_t, uint64_t> channel_counts;
  };

  // Checks the leading magic, the Footer record and the trailing magic; the footer's offsets
  // must lie inside the file.
  Footer ReadFooter() {
    const uint64_t size = file_.size();
    const std::string& p = file_.path();
    if (size < sizeof(mcap::kMagic)) throw BagError("'" + p + "' is too short to be an MCAP file");
    uint8_t magic[8];
    file_.ReadAt(0, magic, 8);
    if (std::memcmp(magic, mcap::kMagic, 8) != 0) {
      throw BagError("'" + p + "' is not an MCAP file (bad leading magic)");
    }
    if (size < 8 + mcap::kRecordPrefix + 8 + mcap::kFooterRecord + 8) {
      throw BagError("'" + p + "' is truncated (no room for header and footer)");
    }
    file_.ReadAt(size - 8, magic, 8);
    Footer footer;
    footer.position = size - 8 - mcap::kFooterRecord;
    const auto bytes = file_.ReadAt(footer.position, mcap::kFooterRecord);
    Parser f(bytes.data(), bytes.size(), p + " footer");
    const uint8_t op = f.U8();
    const uint64_t flen = f.U64();
    if (std::memcmp(magic, mcap::kMagic, 8) != 0 || op != mcap::kFooter ||
        flen != mcap::kFooterContent) {
      throw BagError("'" + p +
                     "' is truncated or corrupt: no footer and trailing magic at the end");
    }
    footer.summary_start = f.U64();
    footer.summary_offset_start = f.U64();
    footer.summary_crc = f.U32();
    if (footer.summary_start > footer.position || footer.summary_offset_start > footer.position ||
        (footer.summary_start != 0 && footer.summary_start < 8)) {
      throw BagError("'" + p + "' footer points outside the file");
    }
    footer.data_end_bound = footer.summary_start          ? footer.summary_start
                            : footer.summary_offset_start ? footer.summary_offset_start
                                                          : footer.position;
    return footer;
  }

  // The CRC covers the summary and summary-offset sections and the footer up to its CRC field.
  void CheckSummaryCrc(const Footer& footer) {
    const uint64_t from = footer.data_end_bound;
    const auto bytes = file_.ReadAt(from, footer.position + mcap::kRecordPrefix + 16 - from);
    const uint32_t got = Crc32(bytes.data(), bytes.size());
    if (got != footer.summary_crc) {
      throw BagError("'" + file_.path() + "' summary CRC mismatch (stored " +
                     std::to_string(footer.summary_crc) + ", computed " + std::to_string(got) +
                     ")");
    }
  }

  // Schemas and channels of the summary section, and its Statistics record if there is one.
  Statistics ReadSummary(const Footer& footer) {
    Statistics stats;
    if (footer.summary_start == 0) return stats;
    const std::string& p = file_.path();
    const uint64_t end =
        footer.summary_offset_start ? footer.summary_offset_start : footer.position;
    if (end < footer.summary_start) throw BagError("'" + p + "' footer offsets are inconsistent");
    const auto bytes = file_.ReadAt(footer.summary_start, end - footer.summary_start);
    Parser s(bytes.data(), bytes.size(), p + " summary");
    while (!s.done()) {
      const uint8_t rop = s.U8();
      Parser r = s.Sub(s.U64(), "record 0x" + Hex(rop));
      if (rop == mcap::kSchema || rop == mcap::kChannel) {
        ParseDefinition(rop, r);
      } else if (rop == mcap::kStatistics) {
        stats.count = r.U64();
        r.U16();  // schema count
        r.U32();  // channel count
        r.U32();  // attachment count
        r.U32();  // metadata count
        r.U32();  // chunk count
        stats.start = r.U64();
        stats.end = r.U64();
        Parser m = r.Sub32("channel_message_counts");
        while (!m.done()) {
          const uint16_t id = m.U16();
          stats.channel_counts[id] = m.U64();
        }
        stats.present = true;
      }
    }
    return stats;
  }

  static std::string Hex(uint8_t v) {
    const char* d = "0123456789abcdef";
    return std::string{d[v >> 4], d[v & 15]};
  }

  // Schema or Channel record (data section, summary or inside a chunk).
  void ParseDefinition(uint8_t op, Parser& r) {
    if (op == mcap::kSchema) {
      const uint16_t id = r.U16();
      SchemaRec s;
      s.name = r.Str();
      s.encoding = r.Str();
      r.Sub32("schema data");
      if (id == 0) return;  // invalid per spec, ignored
      auto it = schemas_.find(id);
      if (it != schemas_.end() &&
          (it->second.name != s.name || it->second.encoding != s.encoding)) {
        r.Fail("schema id " + std::to_string(id) + " redefined differently");
      }
      schemas_[id] = s;
    } else {
      const uint16_t id = r.U16();
      ChannelRec c;
      c.schema_id = r.U16();
      c.topic = r.Str();
      c.message_encoding = r.Str();
      Parser m = r.Sub32("channel metadata");
      while (!m.done()) {
        std::string k = m.Str();
        c.metadata[k] = m.Str();
      }
      if (c.schema_id != 0 && !schemas_.count(c.schema_id)) {
        r.Fail("channel " + std::to_string(id) + " ('" + c.topic + "') refers to unknown schema " +
               std::to_string(c.schema_id));
      }
      auto it = channels_.find(id);
      if (it != channels_.end() &&
          (it->second.topic != c.topic || it->second.schema_id != c.schema_id)) {
        r.Fail("channel id " + std::to_string(id) + " redefined differently");
      }
      if (it == channels_.end()) channels_[id] = c;
    }
  }

  // Walks records from after the leading magic to DataEnd, checking lengths and the data CRC.
  void ScanDataSection(uint64_t bound) {
    const std::string& p = file_.path();
    uint64_t pos = 8;
    uint32_t crc = Crc32(mcap::kMagic, 8);
    bool first = true;
    uint64_t order = 0;
    std::vector<uint8_t> rec;
    for (;;) {
      if (pos == bound) break;  // no DataEnd: tolerated, the section simply ends here
      if (bound - pos < mcap::kRecordPrefix) {
        throw BagError("'" + p + "' data section is truncated at byte " + std::to_string(pos));
      }
      uint8_t prefix[mcap::kRecordPrefix];
      file_.ReadAt(pos, prefix, sizeof(prefix));
      Parser pp(prefix, sizeof(prefix), p);
      const uint8_t op = pp.U8();
      const uint64_t len = pp.U64();
      if (len > bound - pos - mcap::kRecordPrefix) {
        throw BagError("'" + p + "' record 0x" + Hex(op) + " at byte " + std::to_string(pos) +
                       " claims " + std::to_string(len) +
                       " bytes, beyond the data section (truncated or corrupt)");
      }
      if (first && op != mcap::kHeader) {
        throw BagError("'" + p + "' does not start with a Header record");
      }
      first = false;
      if (op == mcap::kDataEnd) {
        rec = file_.ReadAt(pos + mcap::kRecordPrefix, len);
        Parser r(rec.data(), rec.size(), p + " DataEnd");
        const uint32_t stored = r.U32();
        if (stored != 0 && stored != crc) {
          throw BagError("'" + p + "' data section CRC mismatch (stored " + std::to_string(stored) +
                         ", computed " + std::to_string(crc) + ")");
        }
        break;
      }
      rec = file_.ReadAt(pos + mcap::kRecordPrefix, len);
      crc = Crc32Update(crc, prefix, sizeof(prefix));
      crc = Crc32Update(crc, rec.data(), rec.size());
      Parser r(rec.data(), rec.size(),
               p + " record 0x" + Hex(op) + " at byte " + std::to_string(pos));
      switch (op) {
        case mcap::kHeader:
          profile_ = r.Str();
          break;
        case mcap::kSchema:
        case mcap::kChannel:
          ParseDefinition(op, r);
          break;
        case mcap::kMessage: {
          const uint16_t ch = r.U16();
          r.U32();
          const uint64_t t = r.U64();
          r.U64();
          if (!channels_.count(ch)) r.Fail("message on unknown channel " + std::to_string(ch));
          units_.push_back({false, pos, mcap::kRecordPrefix + len, t, t, order++});
          break;
        }
        case mcap::kChunk: {
          const uint64_t start = r.U64();
          const uint64_t end = r.U64();
          r.U64();
          r.U32();
          const std::string comp = r.Str();
          const uint64_t n = r.U64();
          r.Skip(n);
          if (!IsSupportedCompression(comp)) r.Fail("unsupported chunk compression '" + comp + "'");
          units_.push_back({true, pos, mcap::kRecordPrefix + len, start, end, order++});
          break;
        }
        default:
          break;  // indexes, attachments, metadata, unknown opcodes: not needed
      }
      pos += mcap::kRecordPrefix + len;
    }
    if (first) throw BagError("'" + p + "' has no Header record");
  }

  // Inflates a chunk (verifying its CRC) and calls fn(channel, log_time, offset, size) per message.
  template <typename Fn>
  std::shared_ptr<const std::vector<uint8_t>> ReadChunk(const Unit& u, Fn&& fn) {
    const std::string what = file_.path() + " chunk at byte " + std::to_string(u.offset);
    const auto bytes = file_.ReadAt(u.offset + mcap::kRecordPrefix, u.length - mcap::kRecordPrefix);
    Parser r(bytes.data(), bytes.size(), what);
    r.U64();
    r.U64();
    const uint64_t usize = r.U64();
    const uint32_t ucrc = r.U32();
    const std::string comp = r.Str();
    const uint64_t n = r.U64();
    const uint8_t* payload = r.cur();
    r.Skip(n);
    auto raw = std::make_shared<std::vector<uint8_t>>(Decompress(comp, payload, n, usize));
    if (ucrc != 0) {
      const uint32_t got = Crc32(raw->data(), raw->size());
      if (got != ucrc) {
        throw BagError(what + ": CRC mismatch (stored " + std::to_string(ucrc) + ", computed " +
                       std::to_string(got) + ")");
      }
    }
    Parser c(raw->data(), raw->size(), what + " (inflated)");
    while (!c.done()) {
      const uint8_t op = c.U8();
      const uint64_t len = c.U64();
      const size_t rec_off = c.pos();
      Parser rec = c.Sub(len, "record 0x" + Hex(op));
      if (op == mcap::kSchema || op == mcap::kChannel) {
        ParseDefinition(op, rec);
      } else if (op == mcap::kMessage) {
        const uint16_t ch = rec.U16();
        rec.U32();
        const uint64_t t = rec.U64();
        rec.U64();
        if (!channels_.count(ch)) rec.Fail("message on unknown channel " + std::to_string(ch));
        fn(ch, t, rec_off + 22, static_cast<size_t>(len - 22));
      }
    }
    return raw;
  }

  void CountByScanning(std::map<uint16_t, uint64_t>& counts) {
    uint64_t n = 0, lo = 0, hi = 0;
    auto add = [&](uint16_t ch, uint64_t t) {
      ++counts[ch];
      if (n == 0 || t < lo) lo = t;
      if (n == 0 || t > hi) hi = t;
      ++n;
    };
    for (const Unit& u : units_) {
      if (u.is_chunk) {
        ReadChunk(u, [&](uint16_t ch, uint64_t t, size_t, size_t) { add(ch, t); });
      } else {
        uint8_t head[mcap::kRecordPrefix + 2];
        file_.ReadAt(u.offset, head, sizeof(head));
        add(static_cast<uint16_t>(head[9] | head[10] << 8), u.start);
      }
    }
    info_.message_count = n;
    info_.start_ns = static_cast<int64_t>(lo);
    info_.end_ns = static_cast<int64_t>(hi);
  }

  void BuildTopics(const std::map<uint16_t, uint64_t>& counts) {
    std::map<std::string, size_t> by_name;
    for (const auto& [id, ch] : channels_) {
      auto c = counts.find(id);
      const uint64_t n = c == counts.end() ? 0 : c->second;
      auto it = by_name.find(ch.topic);
      if (it != by_name.end()) {
        info_.topics[it->second].message_count += n;
        continue;
      }
      TopicStats ts;
      ts.info.name = ch.topic;
      ts.info.type = ch.schema_id ? schemas_.at(ch.schema_id).name : std::string();
      ts.info.serialization_format = ch.message_encoding;
      auto q = ch.metadata.find("offered_qos_profiles");
      if (q != ch.metadata.end()) ts.info.offered_qos_profiles = q->second;
      ts.message_count = n;
      by_name[ch.topic] = info_.topics.size();
      info_.topics.push_back(ts);
    }
  }

  bool Allowed(uint16_t ch) const {
    return filter_.empty() || filter_.count(channels_.at(ch).topic) > 0;
  }

  void LoadUnit(const Unit& u) {
    if (u.end < seek_time_) return;
    if (u.is_chunk) {
      std::vector<Pending> found;
      auto buf = ReadChunk(u, [&](uint16_t ch, uint64_t t, size_t off, size_t size) {
        if (t >= seek_time_ && Allowed(ch)) found.push_back({t, 0, ch, nullptr, off, size});
      });
      uint64_t i = 0;
      for (auto& m : found) {
        m.seq = (u.order << 32) | i++;
        m.buf = buf;
        heap_.push(std::move(m));
      }
    } else {
      const std::string what = file_.path() + " message at byte " + std::to_string(u.offset);
      auto buf = std::make_shared<std::vector<uint8_t>>(file_.ReadAt(u.offset, u.length));
      Parser r(buf->data(), buf->size(), what);
      r.U8();
      r.U64();
      const uint16_t ch = r.U16();
      if (u.start < seek_time_ || !Allowed(ch)) return;
      const size_t off = mcap::kRecordPrefix + 22;
      if (buf->size() < off) r.Fail("truncated message record");
      heap_.push({u.start, u.order << 32, ch, buf, off, buf->size() - off});
    }
  }

  InputFile file_;
  BagInfo info_;
  std::string profile_;
  std::map<uint16_t, SchemaRec> schemas_;
  std::map<uint16_t, ChannelRec> channels_;
  std::vector<Unit> units_;

  std::unordered_set<std::string> filter_;
  uint64_t seek_time_ = 0;
  size_t cursor_ = 0;
  std::priority_queue<Pending, std::vector<Pending>, PendingLater> heap_;
};

}  // namespace

std::unique_ptr<StorageReader> OpenMcap(const std::string& path) {
  return std::make_unique<McapReader>(path);
}

}  // namespace ppf::bag::detail
