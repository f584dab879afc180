// CanDevice through socketpair(AF_UNIX, SOCK_SEQPACKET): the real recvmsg path with real
// can_frame/canfd_frame bytes (the test machine's kernel has no AF_CAN).
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "hal/socketcan/can_device.hpp"

namespace inertia::hal::socketcan {
namespace {

struct Sample {
  std::uint32_t channel;
  std::int64_t t_ns;
  double value;
  bool valid;
  std::int64_t index = kNoSampleIndex;
};

class RecordingSink final : public SampleSink {
 public:
  bool push(std::uint32_t channel, std::int64_t t_ns, double value, bool valid, std::int64_t sample_index) noexcept override {
    if (refuse) return false;
    samples.push_back({channel, t_ns, value, valid, sample_index});
    return true;
  }
  std::vector<Sample> samples;
  bool refuse = false;
};

// The documented bit numbering, written bit by bit (independent of frame_map.cpp's byte loop).
void reference_put(std::uint8_t* payload, const CanSignal& s, std::uint64_t raw) {
  for (int k = 0; k < s.bit_length; ++k) {
    const bool bit = ((raw >> k) & 1u) != 0;
    std::size_t byte = 0;
    int bit_in_byte = 0;
    if (s.byte_order == ByteOrder::LittleEndian) {
      const std::size_t p = 8u * s.byte_offset + s.bit_offset + static_cast<std::size_t>(k);
      byte = p / 8;
      bit_in_byte = static_cast<int>(p % 8);
    } else {
      const std::size_t q = s.bit_offset + static_cast<std::size_t>(s.bit_length - 1 - k);
      byte = s.byte_offset + q / 8;
      bit_in_byte = 7 - static_cast<int>(q % 8);
    }
    if (bit) payload[byte] |= static_cast<std::uint8_t>(1u << bit_in_byte);
    else payload[byte] &= static_cast<std::uint8_t>(~(1u << bit_in_byte));
  }
}

class CanPair : public ::testing::Test {
 protected:
  void open(CanFrameMap map, std::size_t max_records = 64, bool batch_receive = true, double frame_rate_hz = 0.0,
            std::int64_t (*realtime_ns)() noexcept = nullptr) {
    int sv[2];
    ASSERT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    writer_ = UniqueFd(sv[0]);
    CanDeviceConfig config;
    config.name = "adc";
    config.map = std::move(map);
    config.max_records_per_read = max_records;
    config.batch_receive = batch_receive;
    config.frame_rate_hz = frame_rate_hz;
    config.realtime_ns = realtime_ns;
    std::string why;
    device_ = CanDevice::from_fd(UniqueFd(sv[1]), config, &why);
    ASSERT_NE(device_, nullptr) << why;
    ASSERT_EQ(device_->configure(), Step::Ok) << device_->last_error();
    ASSERT_EQ(device_->activate(), Step::Ok);
  }
  void send_bytes(const void* bytes, std::size_t size) {
    ASSERT_EQ(::send(writer_.get(), bytes, size, 0), static_cast<ssize_t>(size));
  }
  void send_classic(std::uint32_t can_id, std::initializer_list<std::uint8_t> data) {
    can_frame f{};
    f.can_id = can_id;
    f.len = static_cast<std::uint8_t>(data.size());
    std::copy(data.begin(), data.end(), f.data);
    send_bytes(&f, sizeof f);
  }
  void send_error(std::uint32_t cls, std::uint8_t crtl = 0) {
    can_frame f{};
    f.can_id = CAN_ERR_FLAG | cls;
    f.len = CAN_ERR_DLC;
    f.data[1] = crtl;
    send_bytes(&f, sizeof f);
  }
  UniqueFd writer_;
  std::unique_ptr<CanDevice> device_;
  RecordingSink sink_;
};

CanSignal sig(std::string name, std::uint32_t id, std::uint8_t byte, std::uint8_t bit, std::uint8_t len,
              ByteOrder order, bool is_signed, double scale = 1.0, double offset = 0.0, bool ext = false) {
  CanSignal s;  // member by member: CanSignal may grow fields with defaults
  s.name = std::move(name);
  s.id = id;
  s.extended = ext;
  s.byte_offset = byte;
  s.bit_offset = bit;
  s.bit_length = len;
  s.byte_order = order;
  s.is_signed = is_signed;
  s.scale = scale;
  s.offset = offset;
  return s;
}

TEST(FrameMap, DecodesEveryLayoutAsTheDocumentedBitNumberingSays) {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 20000; ++trial) {
    CanSignal s;
    s.bit_length = static_cast<std::uint8_t>(1 + rng() % 64);
    s.bit_offset = static_cast<std::uint8_t>(rng() % 8);
    s.byte_order = (rng() & 1) ? ByteOrder::BigEndian : ByteOrder::LittleEndian;
    const std::size_t span = (s.bit_offset + s.bit_length + 7u) / 8u;
    s.byte_offset = static_cast<std::uint8_t>(rng() % (64 - span + 1));
    const std::uint64_t raw = s.bit_length == 64 ? rng() : rng() & ((std::uint64_t{1} << s.bit_length) - 1);
    std::uint8_t expected[64];
    std::uint8_t written[64];
    for (std::size_t i = 0; i < 64; ++i) expected[i] = written[i] = static_cast<std::uint8_t>(rng());
    reference_put(expected, s, raw);
    insert_raw(written, s, raw);
    ASSERT_EQ(std::memcmp(expected, written, 64), 0) << "trial " << trial;
    ASSERT_EQ(extract_raw(expected, s), raw) << "trial " << trial << " len " << int(s.bit_length)
                                             << " bit " << int(s.bit_offset);
  }
}

TEST(FrameMap, SignExtendsAndScales) {
  CanSignal s = sig("x", 1, 0, 0, 12, ByteOrder::LittleEndian, true, 0.5, 10.0);
  EXPECT_DOUBLE_EQ(to_value(0xFFB, s), 0.5 * -5 + 10.0);
  EXPECT_DOUBLE_EQ(to_value(0x7FF, s), 0.5 * 2047 + 10.0);
  s.is_signed = false;
  EXPECT_DOUBLE_EQ(to_value(0xFFB, s), 0.5 * 4091 + 10.0);
  s.is_signed = true;
  s.bit_length = 64;
  EXPECT_DOUBLE_EQ(to_value(~std::uint64_t{0}, s), 0.5 * -1 + 10.0);
}

TEST(FrameMap, ValidationNamesTheSignal) {
  CanFrameMap map{{sig("ok", 0x10, 0, 0, 16, ByteOrder::LittleEndian, false),
                   sig("wide", 0x10, 60, 0, 64, ByteOrder::LittleEndian, false)}};
  std::string why;
  EXPECT_FALSE(map.is_valid(&why));
  EXPECT_NE(why.find("wide"), std::string::npos) << why;
  map.signals[1] = sig("zero", 0x10, 0, 0, 0, ByteOrder::LittleEndian, false);
  EXPECT_FALSE(map.is_valid(&why));
  EXPECT_NE(why.find("1..64"), std::string::npos) << why;
  map.signals[1] = sig("big_id", 0x800, 0, 0, 8, ByteOrder::LittleEndian, false);
  EXPECT_FALSE(map.is_valid(&why));
  map.signals[1].extended = true;
  EXPECT_TRUE(map.is_valid(&why)) << why;
}

// Found by tests/fuzz/fuzz_can_frame_map: a map whose scale takes a raw value past the
// double range decoded a valid sample as infinity. Such a map is refused at load, naming the signal.
TEST(FrameMap, ScaleThatOverflowsADoubleIsRefused) {
  CanFrameMap map{{sig("huge", 0x10, 0, 0, 64, ByteOrder::LittleEndian, false)}};
  map.signals[0].scale = 1e300;
  std::string why;
  EXPECT_FALSE(map.is_valid(&why));
  EXPECT_NE(why.find("'huge'"), std::string::npos) << why;
  EXPECT_NE(why.find("beyond the range of a double"), std::string::npos) << why;
  map.signals[0].bit_length = 16;   // 65535 * 1e300 is still a double
  EXPECT_TRUE(map.is_valid(&why)) << why;
  EXPECT_TRUE(std::isfinite(to_value(0xFFFF, map.signals[0])));
  map.signals[0].offset = -1.7e308;   // the offset alone at the edge, plus the scaled counts
  map.signals[0].scale = -1e304;
  EXPECT_FALSE(map.is_valid(&why));
}

TEST_F(CanPair, DecodesClassicFrameWithHandWrittenBytes) {
  open(CanFrameMap{{sig("u16", 0x123, 0, 0, 16, ByteOrder::LittleEndian, false),
                    sig("s12", 0x123, 2, 4, 12, ByteOrder::LittleEndian, true, 0.25),
                    sig("be_s16", 0x123, 4, 0, 16, ByteOrder::BigEndian, true),
                    sig("be_u10", 0x123, 6, 3, 10, ByteOrder::BigEndian, false, 1.0, -1.0)}});
  // u16 = 0x1234; s12 = -5 (0xFFB << 4 in a LE word); be_s16 = -300 (0xFED4);
  // be_u10 = 0x2A5: MSB at bit 4 of byte 6 (DBC Motorola start bit 52): 0x15, 0x28.
  send_classic(0x123, {0x34, 0x12, 0xB0, 0xFF, 0xFE, 0xD4, 0x15, 0x28});
  EXPECT_EQ(device_->read_into(sink_), 4u);
  ASSERT_EQ(sink_.samples.size(), 4u);
  EXPECT_EQ(sink_.samples[0].channel, 0u);
  EXPECT_DOUBLE_EQ(sink_.samples[0].value, 0x1234);
  EXPECT_DOUBLE_EQ(sink_.samples[1].value, -5 * 0.25);
  EXPECT_DOUBLE_EQ(sink_.samples[2].value, -300);
  EXPECT_DOUBLE_EQ(sink_.samples[3].value, 0x2A5 - 1.0);
  for (const Sample& s : sink_.samples) EXPECT_TRUE(s.valid);
  EXPECT_EQ(device_->status().classic_frames, 1u);
  EXPECT_EQ(device_->health().samples, 4u);
  EXPECT_EQ(device_->channel_names()[3], "adc.be_u10");
}

TEST_F(CanPair, DecodesFdFrameWithExtendedIdAnd64BitSignals) {
  const std::uint32_t id = 0x18DAF110;
  CanSignal le64 = sig("le64", id, 8, 0, 64, ByteOrder::LittleEndian, false, 1.0, 0.0, true);
  CanSignal be64 = sig("be64", id, 20, 3, 64, ByteOrder::BigEndian, true, 1.0, 0.0, true);
  CanSignal tail = sig("tail", id, 63, 0, 8, ByteOrder::LittleEndian, false, 1.0, 0.0, true);
  open(CanFrameMap{{le64, be64, tail}});
  canfd_frame f{};
  f.can_id = id | CAN_EFF_FLAG;
  f.len = 64;
  f.flags = CANFD_BRS;
  const std::uint64_t a = 0xF123456789ABCDEFull;
  const std::int64_t b = -1234567890123LL;
  reference_put(f.data, le64, a);
  reference_put(f.data, be64, static_cast<std::uint64_t>(b));
  f.data[63] = 0x5A;
  send_bytes(&f, sizeof f);
  // The same id as a standard frame is another frame (0x110 after masking would be a bug).
  send_classic(id & CAN_SFF_MASK, {1, 2, 3, 4, 5, 6, 7, 8});
  EXPECT_EQ(device_->read_into(sink_), 3u);
  ASSERT_EQ(sink_.samples.size(), 3u);
  EXPECT_DOUBLE_EQ(sink_.samples[0].value, static_cast<double>(a));
  EXPECT_DOUBLE_EQ(sink_.samples[1].value, static_cast<double>(b));
  EXPECT_DOUBLE_EQ(sink_.samples[2].value, 0x5A);
  EXPECT_EQ(device_->status().fd_frames, 1u);
  EXPECT_EQ(device_->status().classic_frames, 1u);
  EXPECT_EQ(device_->status().unknown_ids, 1u);
}

TEST_F(CanPair, UnknownIdsAndRemoteFramesAreCountedNotDecoded) {
  open(CanFrameMap{{sig("v", 0x200, 0, 0, 8, ByteOrder::LittleEndian, false)}});
  send_classic(0x201, {1});
  send_classic(0x200 | CAN_RTR_FLAG, {});
  send_classic(0x200 | CAN_EFF_FLAG, {7});
  send_classic(0x200, {9});
  EXPECT_EQ(device_->read_into(sink_), 1u);
  ASSERT_EQ(sink_.samples.size(), 1u);
  EXPECT_DOUBLE_EQ(sink_.samples[0].value, 9);
  EXPECT_EQ(device_->status().unknown_ids, 2u);
  EXPECT_EQ(device_->status().remote_frames, 1u);
}

TEST_F(CanPair, ShortFrameForAKnownIdGivesAnInvalidSample) {
  open(CanFrameMap{{sig("lo", 0x300, 0, 0, 8, ByteOrder::LittleEndian, false),
                    sig("hi", 0x300, 2, 0, 16, ByteOrder::LittleEndian, false)}});
  send_classic(0x300, {42, 0});
  EXPECT_EQ(device_->read_into(sink_), 2u);
  ASSERT_EQ(sink_.samples.size(), 2u);
  EXPECT_TRUE(sink_.samples[0].valid);
  EXPECT_DOUBLE_EQ(sink_.samples[0].value, 42);
  EXPECT_FALSE(sink_.samples[1].valid);
  EXPECT_EQ(device_->health().decode_errors, 1u);
}

// An ADC's frame: a 16-bit reading (bytes 0-1) and a 16-bit counter (bytes 6-7).
CanFrameMap counted_map() {
  CanSignal counter = sig("seq", 0x101, 6, 0, 16, ByteOrder::LittleEndian, false);
  counter.counter = true;
  return CanFrameMap{{sig("v", 0x101, 0, 0, 16, ByteOrder::LittleEndian, true), counter}};
}

TEST_F(CanPair, ShortDuplicateAndOutOfOrderFramesAreRefusedCountedAndOverwriteNothing) {
  open(counted_map(), 256, true, 10000.0);
  // Frames 0..199, the reading of frame n being 1000 + n; among them a frame of 6 bytes (its
  // counter cut off), frame 60 again after 61, and frames 71 and 70 swapped (70 overtaken: lost).
  std::vector<std::uint16_t> sent;
  for (std::uint16_t n = 0; n < 200; ++n) {
    const auto put = [&](std::uint16_t c, std::size_t len = 8) {
      can_frame f{};
      f.can_id = 0x101;
      f.len = static_cast<std::uint8_t>(len);
      const auto v = static_cast<std::uint16_t>(1000 + c);
      f.data[0] = static_cast<std::uint8_t>(v);
      f.data[1] = static_cast<std::uint8_t>(v >> 8);
      f.data[6] = static_cast<std::uint8_t>(c);
      f.data[7] = static_cast<std::uint8_t>(c >> 8);
      send_bytes(&f, sizeof f);
    };
    if (n == 70) continue;
    put(n);
    if (n == 30) put(31, 6);
    if (n == 61) put(60);
    if (n == 71) put(70);
  }
  while (device_->read_into(sink_) > 0) {
  }
  EXPECT_EQ(device_->status().short_frames, 1u);
  EXPECT_EQ(device_->status().duplicate_frames, 1u);
  EXPECT_EQ(device_->status().out_of_order_frames, 1u);
  EXPECT_EQ(device_->status().counter_resets, 0u);
  // Every number once, in order, each with its own frame's reading; 70 missing.
  ASSERT_EQ(sink_.samples.size(), 398u);
  for (std::size_t i = 0; i < sink_.samples.size(); ++i) {
    const Sample& s = sink_.samples[i];
    ASSERT_EQ(s.index, static_cast<std::int64_t>(i / 2 + (i >= 140 ? 1 : 0))) << i;
    ASSERT_EQ(s.channel, i % 2);
    if (s.channel == 0) {
      ASSERT_DOUBLE_EQ(s.value, 1000.0 + static_cast<double>(s.index)) << i;
    }
  }
}

TEST_F(CanPair, ACounterRestartPushesASegmentMarkBeforeItsFramesSamples) {
  open(counted_map(), 256, true, 10000.0);
  for (std::uint16_t c = 40000; c < 40010; ++c) {
    can_frame f{};
    f.can_id = 0x101;
    f.len = 8;
    f.data[6] = static_cast<std::uint8_t>(c);
    f.data[7] = static_cast<std::uint8_t>(c >> 8);
    send_bytes(&f, sizeof f);
  }
  ::usleep(30000);   // the adapter reboots: 30 ms of silence, then it counts from 0
  for (std::uint16_t c = 0; c < 5; ++c) {
    can_frame f{};
    f.can_id = 0x101;
    f.len = 8;
    f.data[6] = static_cast<std::uint8_t>(c);
    send_bytes(&f, sizeof f);
  }
  while (device_->read_into(sink_) > 0) {
  }
  EXPECT_EQ(device_->status().counter_resets, 1u);
  ASSERT_EQ(sink_.samples.size(), 30u + 1u);
  const Sample& mark = sink_.samples[20];
  EXPECT_EQ(mark.channel, kSegmentStart);
  // Numbered on from the receive time: about 300 samples of 10 kHz after the last before it
  // (the sleep, and a scheduler's slack of at most 20 ms).
  EXPECT_GE(mark.index, 40009 + 300);
  EXPECT_LE(mark.index, 40009 + 300 + 200);
  for (std::size_t i = 21; i < sink_.samples.size(); ++i) EXPECT_EQ(sink_.samples[i].index, mark.index + static_cast<std::int64_t>(i - 21) / 2);
}

TEST_F(CanPair, AWrappingCountGoesOnPastItsWidth) {
  // A counter card's signed 32-bit count, 1 urad per step: 340 turns and on.
  CanSignal count = sig("table", 0x301, 0, 0, 32, ByteOrder::LittleEndian, true, 1e-6);
  count.wraps = true;
  open(CanFrameMap{{count}});
  const std::int64_t start = 2'147'483'000;   // 600 steps below INT32_MAX
  for (std::int64_t k = 0; k < 40; ++k) {
    const std::int64_t truth = start + 37 * k - (k > 30 ? 80 * (k - 30) : 0);   // through the wrap, and back
    can_frame f{};
    f.can_id = 0x301;
    f.len = 4;
    const auto raw = static_cast<std::uint32_t>(truth);
    for (int b = 0; b < 4; ++b) f.data[b] = static_cast<std::uint8_t>(raw >> (8 * b));
    send_bytes(&f, sizeof f);
    ASSERT_EQ(device_->read_into(sink_), 1u);
    EXPECT_NEAR(sink_.samples.back().value, 1e-6 * static_cast<double>(truth), 1e-9) << k;
  }
}

TEST_F(CanPair, ReadingsOutsideTheirRangeAreInvalidKeptAndCounted) {
  CanSignal v = sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, true, 0.5);
  v.min = -10.0;
  v.max = 20.0;
  open(CanFrameMap{{v}});
  for (const std::int8_t raw : {std::int8_t{0}, std::int8_t{40}, std::int8_t{41}, std::int8_t{-20}, std::int8_t{-21}, std::int8_t{127}})
    send_classic(0x10, {static_cast<std::uint8_t>(raw)});
  EXPECT_EQ(device_->read_into(sink_), 6u);
  const bool expected_valid[6] = {true, true, false, true, false, false};
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(sink_.samples[i].valid, expected_valid[i]) << i;
  EXPECT_DOUBLE_EQ(sink_.samples[2].value, 20.5) << "the reading is kept, marked";
  EXPECT_EQ(device_->status().range_faults, 3u);
}

TEST(ReceiveControl, CarriesTheStampAndTheKernelsDropCount) {
  // The control messages as the kernel lays them out (SOL_SOCKET: SCM_TIMESTAMPNS, SO_RXQ_OVFL);
  // an AF_UNIX socket does not report drops, so they are built here.
  alignas(cmsghdr) std::uint8_t control[CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t))] = {};
  msghdr msg{};
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  cmsghdr* c = CMSG_FIRSTHDR(&msg);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SCM_TIMESTAMPNS;
  c->cmsg_len = CMSG_LEN(sizeof(timespec));
  const timespec ts{1700000000, 123456789};
  std::memcpy(CMSG_DATA(c), &ts, sizeof ts);
  c = CMSG_NXTHDR(&msg, c);
  ASSERT_NE(c, nullptr);
  c->cmsg_level = SOL_SOCKET;
  c->cmsg_type = SO_RXQ_OVFL;
  c->cmsg_len = CMSG_LEN(sizeof(std::uint32_t));
  const std::uint32_t drops = 4242;
  std::memcpy(CMSG_DATA(c), &drops, sizeof drops);
  const ReceiveControl got = read_receive_control(msg);
  EXPECT_EQ(got.realtime_ns, 1700000000LL * 1'000'000'000 + 123456789);
  EXPECT_TRUE(got.has_drops);
  EXPECT_EQ(got.drops, 4242u);
  msg.msg_controllen = CMSG_SPACE(sizeof(timespec));   // the stamp alone
  EXPECT_FALSE(read_receive_control(msg).has_drops);
}

// CLOCK_REALTIME as the device sees it, stepped by the test (NTP setting the clock at boot).
std::atomic<std::int64_t> g_realtime_step_ns{0};
std::int64_t stepped_realtime_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec + g_realtime_step_ns.load();
}

TEST_F(CanPair, AStepOfTheRealtimeClockNeverMakesAStampEarly) {
  // Frames are stamped on CLOCK_REALTIME by the kernel; the device maps them with the offset it
  // reads. A step of +50 ms between the frames and the read would put their stamps 50 ms early,
  // which would pull a clock fit that follows the earliest stamps. The kernel's stamps here stay
  // on the unstepped clock, so the step the device sees is taken back before the frames after it
  // (two steps, +50 ms and back): the reads across either use the read's time, late but never
  // early, and the read after them the kernel's stamps again. Checked against CLOCK_MONOTONIC
  // around each send: no stamp is ever before its frame was sent.
  g_realtime_step_ns = 0;
  open(CanFrameMap{{sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false)}}, 64, true, 0.0, stepped_realtime_ns);
  std::vector<std::int64_t> sent_after;   // monotonic time before each send: its stamp is not earlier
  auto send_some = [&](int n) {
    for (int i = 0; i < n; ++i) {
      sent_after.push_back(monotonic_now_ns());
      send_classic(0x10, {static_cast<std::uint8_t>(sent_after.size())});
      ::usleep(1000);
    }
  };
  send_some(5);
  device_->read_into(sink_);
  EXPECT_EQ(device_->status().clock_steps, 0u);
  for (const std::int64_t step_ns : {50'000'000LL, -50'000'000LL}) {
    send_some(5);
    g_realtime_step_ns += step_ns;
    const std::int64_t read_at = monotonic_now_ns();
    device_->read_into(sink_);
    for (std::size_t i = sink_.samples.size() - 5; i < sink_.samples.size(); ++i) {
      EXPECT_GE(sink_.samples[i].t_ns, sent_after[i]) << "step " << step_ns << ": frame " << i << " stamped early";
      EXPECT_GE(sink_.samples[i].t_ns, read_at) << "the read's time stands in for the stamp";
    }
  }
  send_some(5);
  device_->read_into(sink_);   // no step since the previous read: the kernel's stamps again
  for (std::size_t i = sink_.samples.size() - 5; i < sink_.samples.size(); ++i) {
    EXPECT_GE(sink_.samples[i].t_ns, sent_after[i] - 1'000'000);
    EXPECT_LT(sink_.samples[i].t_ns, sent_after[i] + 1'000'000) << "the kernel's stamp, not the read's time";
  }
  EXPECT_EQ(device_->status().clock_steps, 2u);
  ASSERT_EQ(sink_.samples.size(), 20u);
}

TEST_F(CanPair, TheReceiveBufferIsAskedForOneSecondOfFrames) {
  open(counted_map(), 64, true, 1000.0);
  const ReceiveBuffer& b = device_->receive_buffer();
  EXPECT_EQ(b.wanted, 1000u * CanDevice::kBufferBytesPerFrame);
  int have = 0;
  socklen_t len = sizeof have;
  ASSERT_EQ(::getsockopt(device_->wait_fd(), SOL_SOCKET, SO_RCVBUF, &have, &len), 0);
  EXPECT_EQ(b.granted, static_cast<std::size_t>(have));
  // Without CAP_NET_ADMIN the kernel caps the request at net.core.rmem_max (and doubles it).
  std::size_t rmem_max = 0;
  std::ifstream("/proc/sys/net/core/rmem_max") >> rmem_max;
  ASSERT_GT(rmem_max, 0u);
  EXPECT_GE(b.granted, std::min(b.wanted, 2 * rmem_max));
}

TEST_F(CanPair, ErrorFramesDriveBusStateAndRestartRecovers) {
  open(CanFrameMap{{sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false)}});
  send_error(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_WARNING);
  device_->read_into(sink_);
  EXPECT_EQ(device_->status().bus_state, BusState::ErrorWarning);
  send_error(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE | CAN_ERR_CRTL_RX_OVERFLOW);
  device_->read_into(sink_);
  EXPECT_EQ(device_->status().bus_state, BusState::ErrorPassive);
  EXPECT_EQ(device_->status().controller_overflows, 1u);
  send_error(CAN_ERR_BUSOFF);
  send_error(CAN_ERR_BUSOFF);                        // repeated: one bus-off event
  send_error(CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE);     // does not end bus-off by itself
  device_->read_into(sink_);
  EXPECT_EQ(device_->status().bus_state, BusState::BusOff);
  EXPECT_EQ(device_->status().bus_off_events, 1u);
  send_error(CAN_ERR_RESTARTED);
  send_classic(0x10, {3});
  EXPECT_EQ(device_->read_into(sink_), 1u);
  EXPECT_EQ(device_->status().bus_state, BusState::ErrorActive);
  EXPECT_EQ(device_->status().restarts, 1u);
  EXPECT_EQ(device_->status().error_frames, 6u);
  EXPECT_EQ(sink_.samples.size(), 1u);               // error frames never become samples
  send_error(CAN_ERR_BUSOFF);
  device_->read_into(sink_);
  EXPECT_EQ(device_->status().bus_off_events, 2u);
}

TEST_F(CanPair, FragmentsAndBadLengthsAreMalformedAndDecodingContinues) {
  open(CanFrameMap{{sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false)}});
  const std::uint8_t fragment[10] = {0x10, 0, 0, 0, 1, 0, 0, 0, 5, 0};
  send_bytes(fragment, sizeof fragment);
  can_frame bad{};
  bad.can_id = 0x10;
  bad.len = 9;  // classic payload is at most 8
  send_bytes(&bad, sizeof bad);
  std::uint8_t oversized[80] = {};
  send_bytes(oversized, sizeof oversized);
  send_classic(0x10, {77});
  EXPECT_EQ(device_->read_into(sink_), 1u);
  EXPECT_EQ(device_->health().malformed, 3u);
  ASSERT_EQ(sink_.samples.size(), 1u);
  EXPECT_DOUBLE_EQ(sink_.samples[0].value, 77);
}

TEST_F(CanPair, TimestampsComeFromSoTimestampnsOnMonotonicClock) {
  open(CanFrameMap{{sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false)}});
  const std::int64_t before = monotonic_now_ns();
  send_classic(0x10, {1});
  ::usleep(20000);
  send_classic(0x10, {2});
  const std::int64_t sent = monotonic_now_ns();
  ::usleep(50000);  // the stamps are reception times, not the time of read_into()
  EXPECT_EQ(device_->read_into(sink_), 2u);
  ASSERT_EQ(sink_.samples.size(), 2u);
  EXPECT_EQ(device_->status().kernel_timestamps, 2u);
  // Slack of 5 ms for the realtime->monotonic mapping; far below the 50 ms wait.
  constexpr std::int64_t kSlack = 5'000'000;
  EXPECT_GE(sink_.samples[0].t_ns, before - kSlack);
  EXPECT_LE(sink_.samples[1].t_ns, sent + kSlack);
  EXPECT_GE(sink_.samples[1].t_ns - sink_.samples[0].t_ns, 15'000'000);
}

TEST_F(CanPair, ReadIsBoundedAndNeverBlocks) {
  open(CanFrameMap{{sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false)}}, 16);
  EXPECT_EQ(device_->read_into(sink_), 0u);  // nothing pending: returns at once
  for (int i = 0; i < 40; ++i) send_classic(0x10, {static_cast<std::uint8_t>(i)});
  EXPECT_EQ(device_->read_into(sink_), 16u);
  EXPECT_EQ(device_->read_into(sink_), 16u);
  EXPECT_EQ(device_->read_into(sink_), 8u);
  EXPECT_EQ(device_->read_into(sink_), 0u);
  for (int i = 0; i < 40; ++i) EXPECT_DOUBLE_EQ(sink_.samples[static_cast<std::size_t>(i)].value, i);
}

TEST_F(CanPair, LifecycleDiscardsStaleFramesAndCountsSinkDrops) {
  open(CanFrameMap{{sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false)}});
  ASSERT_EQ(device_->deactivate(), Step::Ok);
  send_classic(0x10, {1});
  EXPECT_EQ(device_->read_into(sink_), 0u);  // inactive
  ASSERT_EQ(device_->activate(), Step::Ok);  // discards the frame queued while inactive
  EXPECT_EQ(device_->read_into(sink_), 0u);
  sink_.refuse = true;
  send_classic(0x10, {2});
  EXPECT_EQ(device_->read_into(sink_), 0u);
  EXPECT_EQ(device_->health().sink_drops, 1u);
  writer_.reset();
  device_->read_into(sink_);
  EXPECT_TRUE(device_->status().peer_closed);
}

// recvmmsg (a batch of records per call) and the one-record recvmsg fallback see the same
// stream: records of every kind, decoded into identical samples and counters; the batch path
// needs one call per kReceiveBatch records (the point of it), the fallback one per record.
class CanPaths : public CanPair, public ::testing::WithParamInterface<bool> {};

TEST_P(CanPaths, EveryRecordKindDecodesTheSameInBatchesAsOneByOne) {
  const bool batch = GetParam();
  open(CanFrameMap{{sig("a", 0x10, 0, 0, 16, ByteOrder::LittleEndian, true, 0.5),
                    sig("b", 0x10, 2, 0, 8, ByteOrder::LittleEndian, false),
                    sig("w", 0x200, 0, 0, 32, ByteOrder::BigEndian, false, 1.0, 0.0, true)}},
       CanDevice::kMaxRecordsPerReadLimit, batch);
  // Rounds of one whole batch: the socketpair's send buffer holds them (the writer blocks), and
  // the expected number of calls is exact.
  constexpr std::size_t kRound = CanDevice::kReceiveBatch;
  constexpr std::size_t kRounds = 16;
  const int sndbuf = 1 << 20;  // headroom over the default (capped by net.core.wmem_max)
  ASSERT_EQ(::setsockopt(writer_.get(), SOL_SOCKET, SO_SNDBUF, &sndbuf, sizeof sndbuf), 0);
  std::mt19937 rng(11);
  std::vector<double> want_a, want_w;
  std::uint64_t malformed = 0, unknown = 0, errors = 0;
  std::size_t pushed = 0;
  for (std::size_t round = 0; round < kRounds; ++round) {
    for (std::size_t i = 0; i < kRound; ++i) {
      switch (rng() % 8) {
        case 0: {  // an FD frame with an extended id
          canfd_frame f{};
          f.can_id = 0x200 | CAN_EFF_FLAG;
          f.len = 8;
          const std::uint32_t v = static_cast<std::uint32_t>(rng());
          reference_put(f.data, sig("w", 0x200, 0, 0, 32, ByteOrder::BigEndian, false), v);
          want_w.push_back(static_cast<double>(v));
          send_bytes(&f, sizeof f);
          break;
        }
        case 1: {
          const std::uint8_t fragment[10] = {};
          send_bytes(fragment, sizeof fragment);
          ++malformed;
          break;
        }
        case 2:
          send_classic(0x11, {1, 2});
          ++unknown;
          break;
        case 3:
          send_error(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_WARNING);
          ++errors;
          break;
        default: {
          const auto raw = static_cast<std::int16_t>(rng());
          const auto u = static_cast<std::uint16_t>(raw);
          send_classic(0x10, {static_cast<std::uint8_t>(u), static_cast<std::uint8_t>(u >> 8), 7});
          want_a.push_back(0.5 * raw);
          break;
        }
      }
    }
    pushed += device_->read_into(sink_);
    EXPECT_EQ(device_->read_into(sink_), 0u);
  }
  EXPECT_EQ(pushed, 2 * want_a.size() + want_w.size());
  std::vector<double> got_a, got_w;
  for (const Sample& s : sink_.samples) {
    EXPECT_TRUE(s.valid);
    if (s.channel == 0) got_a.push_back(s.value);
    if (s.channel == 1) {
      EXPECT_DOUBLE_EQ(s.value, 7);
    }
    if (s.channel == 2) got_w.push_back(s.value);
  }
  EXPECT_EQ(got_a, want_a);
  EXPECT_EQ(got_w, want_w);
  const CanStatus& st = device_->status();
  EXPECT_EQ(device_->health().malformed, malformed);
  EXPECT_EQ(st.unknown_ids, unknown);
  EXPECT_EQ(st.error_frames, errors);
  EXPECT_EQ(st.kernel_timestamps, kRound * kRounds);
  EXPECT_EQ(st.receive_calls, batch ? kRounds : kRound * kRounds);
  // Records queued before the peer closed are all decoded, then the end is reported.
  send_classic(0x10, {1, 0, 3});
  send_classic(0x10, {2, 0, 3});
  writer_.reset();
  sink_.samples.clear();
  EXPECT_EQ(device_->read_into(sink_), 4u);
  EXPECT_TRUE(device_->status().peer_closed);
  ASSERT_EQ(sink_.samples.size(), 4u);
  EXPECT_DOUBLE_EQ(sink_.samples[0].value, 0.5);
  EXPECT_DOUBLE_EQ(sink_.samples[2].value, 1.0);
}

INSTANTIATE_TEST_SUITE_P(ReceivePath, CanPaths, ::testing::Values(true, false),
                         [](const ::testing::TestParamInfo<bool>& p) { return p.param ? "recvmmsg" : "recvmsg"; });

TEST(CanDeviceOpen, InterfaceOpenFailsWithAReason) {
  CanDeviceConfig config;
  config.interface = "nosuchcan9";
  config.map.signals.push_back(sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false));
  std::string why;
  EXPECT_EQ(CanDevice::open_interface(config, &why), nullptr);
  const int probe = ::socket(PF_CAN, SOCK_RAW, 1 /*CAN_RAW*/);
  if (probe < 0) {
    EXPECT_NE(why.find("no SocketCAN"), std::string::npos) << why;  // a kernel without AF_CAN
  } else {
    ::close(probe);
    EXPECT_NE(why.find("nosuchcan9"), std::string::npos) << why;   // a kernel with CAN
  }
}

TEST(CanDeviceOpen, RefusesDescriptorsWithoutRecordBoundaries) {
  CanDeviceConfig config;
  config.map.signals.push_back(sig("v", 0x10, 0, 0, 8, ByteOrder::LittleEndian, false));
  int p[2];
  ASSERT_EQ(::pipe(p), 0);
  UniqueFd keep(p[1]);
  std::string why;
  EXPECT_EQ(CanDevice::from_fd(UniqueFd(p[0]), config, &why), nullptr);
  EXPECT_FALSE(why.empty());
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, sv), 0);
  UniqueFd other(sv[1]);
  EXPECT_EQ(CanDevice::from_fd(UniqueFd(sv[0]), config, &why), nullptr);
  EXPECT_NE(why.find("stream"), std::string::npos) << why;
  config.map.signals.clear();
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
  UniqueFd other2(sv[1]);
  EXPECT_EQ(CanDevice::from_fd(UniqueFd(sv[0]), config, &why), nullptr);
  EXPECT_NE(why.find("no signals"), std::string::npos) << why;
}

}  // namespace
}  // namespace inertia::hal::socketcan
