#include "hal/wire_sim/encoder_wire.hpp"

#include <fcntl.h>
#include <linux/gpio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <limits>

namespace inertia::hal::wire_sim {
namespace {

static_assert(sizeof(gpioevent_data) == 16);

using Flags = std::array<std::atomic<bool>, gpiod::kEdgeLineCount>;
using Stamps = std::array<std::atomic<std::int64_t>, gpiod::kEdgeLineCount>;

std::uint64_t pack_levels(bool a, bool b, std::int64_t t_ns) {
  return (static_cast<std::uint64_t>(std::max<std::int64_t>(t_ns, 0)) << 2) | (b ? 2u : 0u) | (a ? 1u : 0u);
}

class PipeEdgeSource final : public gpiod::EdgeSource {
 public:
  PipeEdgeSource(std::shared_ptr<const Flags> level, std::shared_ptr<const std::atomic<std::uint64_t>> levels,
                 std::shared_ptr<const Stamps> through, std::array<int, gpiod::kEdgeLineCount> fds, std::shared_ptr<void> keep)
      : level_(std::move(level)), levels_(std::move(levels)), through_(std::move(through)), fds_(fds), keep_(std::move(keep)) {}
  [[nodiscard]] int event_fd(gpiod::EdgeLine line) const noexcept override {
    return fds_[static_cast<std::size_t>(line)];
  }
  [[nodiscard]] bool level(gpiod::EdgeLine line) const noexcept override {
    return (*level_)[static_cast<std::size_t>(line)].load();
  }
  [[nodiscard]] gpiod::LineLevels levels() const noexcept override {
    const std::uint64_t w = levels_->load(std::memory_order_acquire);
    if (w == ~std::uint64_t{0}) return {level(gpiod::EdgeLine::A), level(gpiod::EdgeLine::B), std::numeric_limits<std::int64_t>::min()};
    return {(w & 1u) != 0, (w & 2u) != 0, static_cast<std::int64_t>(w >> 2)};
  }
  [[nodiscard]] std::int64_t complete_through_ns(gpiod::EdgeLine line) const noexcept override {
    // Acquire: pairs with advance()'s release, so the records written before are readable.
    return (*through_)[static_cast<std::size_t>(line)].load(std::memory_order_acquire);
  }

 private:
  std::shared_ptr<const Flags> level_;
  std::shared_ptr<const std::atomic<std::uint64_t>> levels_;
  std::shared_ptr<const Stamps> through_;
  std::array<int, gpiod::kEdgeLineCount> fds_;
  std::shared_ptr<void> keep_;  // owns the read ends
};

}  // namespace

std::unique_ptr<EncoderWire> EncoderWire::create(const Lines& lines, std::string* why) {
  std::unique_ptr<EncoderWire> wire(new EncoderWire());
  wire->shared_ = std::make_shared<Shared>();
  const bool used[gpiod::kEdgeLineCount] = {true, true, lines.marker, lines.trigger};
  for (std::size_t i = 0; i < gpiod::kEdgeLineCount; ++i) {
    if (!used[i]) continue;
    int p[2];
    if (::pipe2(p, O_CLOEXEC | O_NONBLOCK) != 0) {
      if (why) *why = std::string("pipe2: ") + std::strerror(errno);
      return nullptr;
    }
    wire->shared_->read_end[i] = UniqueFd(p[0]);
    wire->write_end_[i] = UniqueFd(p[1]);
  }
  wire->shared_->level[0] = lines.a0;
  wire->shared_->level[1] = lines.b0;
  for (auto& t : wire->shared_->through) t = std::numeric_limits<std::int64_t>::min();
  return wire;
}

std::unique_ptr<gpiod::EdgeSource> EncoderWire::take_source() {
  if (taken_) return nullptr;
  taken_ = true;
  std::array<int, gpiod::kEdgeLineCount> fds{};
  for (std::size_t i = 0; i < gpiod::kEdgeLineCount; ++i) fds[i] = shared_->read_end[i].get();
  auto level = std::shared_ptr<const Flags>(shared_, &shared_->level);
  auto levels = std::shared_ptr<const std::atomic<std::uint64_t>>(shared_, &shared_->levels);
  auto through = std::shared_ptr<const Stamps>(shared_, &shared_->through);
  return std::make_unique<PipeEdgeSource>(std::move(level), std::move(levels), std::move(through), fds, shared_);
}

bool EncoderWire::write(const gpiod::EdgeEvent& event) {
  gpioevent_data record{};
  record.timestamp = static_cast<__u64>(event.t_ns);
  record.id = event.rising ? GPIOEVENT_EVENT_RISING_EDGE : GPIOEVENT_EVENT_FALLING_EDGE;
  if (!write_raw(event.line, &record, sizeof record)) return false;
  shared_->level[static_cast<std::size_t>(event.line)] = event.rising;
  shared_->levels.store(pack_levels(shared_->level[0].load(), shared_->level[1].load(), event.t_ns), std::memory_order_release);
  return true;
}

void EncoderWire::set_levels(bool a, bool b, std::int64_t t_ns) {
  shared_->level[0] = a;
  shared_->level[1] = b;
  shared_->levels.store(pack_levels(a, b, t_ns), std::memory_order_release);
}

void EncoderWire::advance(gpiod::EdgeLine line, std::int64_t t_ns) {
  shared_->through[static_cast<std::size_t>(line)].store(t_ns, std::memory_order_release);
}

void EncoderWire::advance_all(std::int64_t t_ns) {
  for (std::size_t i = 0; i < gpiod::kEdgeLineCount; ++i) advance(static_cast<gpiod::EdgeLine>(i), t_ns);
}

bool EncoderWire::write_raw(gpiod::EdgeLine line, const void* bytes, std::size_t size) {
  const int fd = write_end_[static_cast<std::size_t>(line)].get();
  if (fd < 0) return false;
  // Writes up to PIPE_BUF are atomic, so a record is never split between reads.
  return ::write(fd, bytes, size) == static_cast<ssize_t>(size);
}

}  // namespace inertia::hal::wire_sim
