// libFuzzer target: the LCM event-log reader behind characterize --log and diagnose --log
// (analyzer/fusion/log_dataset: feed_log over common/lcm EventLogReader): torn tails, garbage,
// huge lengths. The input is written as a log file and read whole, the way characterize reads
// it, for the sensor acc1 (config/sim-paper-daq.toml's, the seeds' bench). Bad input must be an
// InputError or a note on `messages`; the allocation a record may cause is bounded by the file.
#include <sstream>

#include "analyzer/fusion/log_dataset.hpp"
#include "common/input_error.hpp"
#include "common/lcm/event_log_reader.hpp"
#include "tests/fuzz/fuzz_support.hpp"

using namespace inertia;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static fuzz::ScratchCleanup cleanup;
  const std::filesystem::path file = fuzz::scratch_dir() / "fuzz.lcmlog";
  fuzz::write_file(file, std::string_view(reinterpret_cast<const char*>(data), size));
  // The reader alone: records never exceed the file, and it always stops.
  try {
    EventLogReader reader(file);
    LogRecord r;
    std::uint64_t bytes = 0;
    while (reader.next(r)) bytes += r.channel.size() + r.data.size();
    if (bytes > size) __builtin_trap();
  } catch (const InputError&) {
  }
  std::ostringstream messages;
  fusion::AssemblerOptions options;
  options.min_segment_s = 0.005;
  try {
    (void)fusion::log_dataset(file, "acc1", messages, options);
  } catch (const InputError&) {
  }
  return 0;
}
