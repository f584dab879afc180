#include "common/lcm/event_log_reader.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>

#include "common/input_error.hpp"

namespace inertia {
namespace {

constexpr std::uint32_t kSyncWord = 0xEDA1DA01;   // lcm/eventlog.c MAGIC
constexpr std::size_t kHeaderSize = 4 + 8 + 8 + 4 + 4;

std::uint64_t big_endian(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v = (v << 8) | p[i];
  return v;
}

}  // namespace

EventLogReader::EventLogReader(const std::filesystem::path& file) : file_(file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw InputError(SourcePosition{file.string(), 0, 0}, "no such log file");
  stream_ = std::fopen(file.c_str(), "rb");
  if (stream_ == nullptr)
    throw InputError(SourcePosition{file.string(), 0, 0}, fmt::format("cannot open the log: {}", std::strerror(errno)));
  size_ = std::filesystem::file_size(file, ec);
  std::uint8_t head[4] = {0, 0, 0, 0};
  if (ec || std::fread(head, 1, 4, stream_) != 4 || big_endian(head, 4) != kSyncWord) {
    std::fclose(stream_);
    stream_ = nullptr;
    throw InputError(file.string() + ": byte 0: not an LCM event log (no LCM sync word 0xEDA1DA01)");
  }
  std::rewind(stream_);
}

EventLogReader::~EventLogReader() {
  if (stream_ != nullptr) std::fclose(stream_);
}

bool EventLogReader::stop(std::string reason) {
  stopped_ = true;
  stop_reason_ = std::move(reason);
  return false;
}

bool EventLogReader::next(LogRecord& record) {
  if (stopped_) return false;
  const std::uint64_t left = size_ - offset_;
  if (left == 0) {
    stopped_ = true;
    return false;
  }
  const std::int64_t index = records_;
  if (left < kHeaderSize)
    return stop(fmt::format("the log ends inside event {} at byte {} (its header needs {} bytes, {} remain)", index,
                            offset_, kHeaderSize, left));
  std::uint8_t h[kHeaderSize];
  if (std::fread(h, 1, kHeaderSize, stream_) != kHeaderSize)
    return stop(fmt::format("reading event {} at byte {} failed: {}", index, offset_, std::strerror(errno)));
  if (big_endian(h, 4) != kSyncWord)
    return stop(fmt::format("byte {}: event {} does not start with the LCM sync word: not a log record from here on",
                            offset_, index));
  const auto channel_length = static_cast<std::int32_t>(big_endian(h + 20, 4));
  const auto data_length = static_cast<std::int32_t>(big_endian(h + 24, 4));
  if (channel_length < 1 || channel_length > kMaxChannelLength || data_length < 0)
    return stop(fmt::format("byte {}: event {} has channel length {} and data length {}: not a log record from here on",
                            offset_, index, channel_length, data_length));
  const std::uint64_t body = static_cast<std::uint64_t>(channel_length) + static_cast<std::uint64_t>(data_length);
  if (body > left - kHeaderSize)
    return stop(fmt::format("the log ends inside event {} at byte {} (its channel and data need {} bytes, {} remain)",
                            index, offset_, body, left - kHeaderSize));
  record.event_number = static_cast<std::int64_t>(big_endian(h + 4, 8));
  record.utime = static_cast<std::int64_t>(big_endian(h + 12, 8));
  record.offset = offset_;
  record.channel.resize(static_cast<std::size_t>(channel_length));
  record.data.resize(static_cast<std::size_t>(data_length));
  if (std::fread(record.channel.data(), 1, record.channel.size(), stream_) != record.channel.size() ||
      std::fread(record.data.data(), 1, record.data.size(), stream_) != record.data.size())
    return stop(fmt::format("reading event {} at byte {} failed (the file shrank?)", index, offset_));
  offset_ += kHeaderSize + body;
  ++records_;
  return true;
}

}  // namespace inertia
