#include "daq/journal.hpp"

#include <sys/stat.h>
#include <sys/uio.h>
#include <systemd/sd-journal.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <mutex>

namespace inertia::daq {

bool stderr_is_journal() {
  const char* stream = std::getenv("JOURNAL_STREAM");
  if (stream == nullptr) return false;
  struct stat st{};
  if (::fstat(2, &st) != 0) return false;
  unsigned long long dev = 0, ino = 0;
  if (std::sscanf(stream, "%llu:%llu", &dev, &ino) != 2) return false;
  return static_cast<unsigned long long>(st.st_dev) == dev && static_cast<unsigned long long>(st.st_ino) == ino;
}

namespace {

/// One structured entry (MESSAGE, PRIORITY, SYSLOG_IDENTIFIER first, then `fields`) and its
/// stderr line unless stderr is the journal.
void send_entry(const std::string& text, int priority, std::vector<std::string> fields) {
  const std::string message = "inertia-daqd: " + text;
  fields.insert(fields.begin(), {"MESSAGE=" + message, "PRIORITY=" + std::to_string(priority), "SYSLOG_IDENTIFIER=inertia-daqd"});
  std::vector<iovec> iov;
  for (std::string& f : fields) iov.push_back(iovec{f.data(), f.size()});
  // The supervisor, the executive and the command thread all write here, rarely. One writer at a
  // time: libsystemd opens its journal socket on first use from whichever thread comes first, and
  // that is ordered for the thread sanitizer only by this lock (libsystemd is not instrumented);
  // the stderr lines do not interleave either.
  static std::mutex writer;
  const std::lock_guard lock(writer);
  // Fails (without a journal socket) quietly: the stderr line below is then the record.
  (void)sd_journal_sendv(iov.data(), static_cast<int>(iov.size()));
  if (!stderr_is_journal()) std::cerr << (message + "\n") << std::flush;
}

}  // namespace

void journal_fault(const FaultEntry& e) {
  std::vector<std::string> fields{"DEVICE=" + e.device, "FAULT=" + e.fault, "FAULT_STATE=" + e.state};
  if (e.samples_lost) fields.push_back("SAMPLES_LOST=" + std::to_string(*e.samples_lost));
  if (e.messages_lost) fields.push_back("MESSAGES_LOST=" + std::to_string(*e.messages_lost));
  send_entry(e.message, e.priority, std::move(fields));
}

void journal_plan(const PlanEntry& e) {
  std::vector<std::string> fields{"PLAN_EVENT=" + e.event};
  if (!e.case_name.empty()) fields.push_back("CASE=" + e.case_name);
  if (!e.phase.empty()) fields.push_back("PHASE=" + e.phase);
  if (!e.device.empty()) fields.push_back("DEVICE=" + e.device);
  send_entry(e.message, e.priority, std::move(fields));
}

void journal_command(const CommandEntry& e) {
  send_entry(e.message, e.priority, {"OPERATOR=" + e.who, "COMMAND=" + e.command, "RESULT=" + e.result});
}

FaultJournal::FaultJournal(std::vector<const DeviceSlot*> slots, std::int64_t now_ns) {
  for (const DeviceSlot* s : slots) watched_.push_back(Watched{s, 0, snapshot(*s, now_ns), {}});
}

FaultJournal::Snapshot FaultJournal::snapshot(const DeviceSlot& slot, std::int64_t now_ns) {
  const auto samples = static_cast<double>(slot.samples.load(std::memory_order_relaxed));
  const auto invalid = static_cast<double>(slot.invalid_samples.load(std::memory_order_relaxed));
  const double channels = slot.channels.empty() ? 1.0 : static_cast<double>(slot.channels.size());
  return Snapshot{now_ns, (samples - invalid) / channels};
}

std::uint64_t FaultJournal::lost(const DeviceSlot& slot, const Snapshot& from, const Snapshot& to) {
  const double expected = slot.nominal_rate_hz * static_cast<double>(to.t_ns - from.t_ns) * 1e-9;
  const double missing = expected - (to.valid_per_channel - from.valid_per_channel);
  return missing > 0.0 ? static_cast<std::uint64_t>(std::llround(missing)) : 0;
}

void FaultJournal::update(std::int64_t now_ns) {
  for (Watched& w : watched_) {
    const Snapshot now = snapshot(*w.slot, now_ns);
    const std::uint32_t faults = w.slot->faults.load(std::memory_order_relaxed);
    for (unsigned bit = 0; bit < 32; ++bit) {
      const std::uint32_t mask = 1u << bit;
      if ((faults & mask) == (w.faults & mask)) continue;
      const std::string name = fault_names(mask).empty() ? "fault-bit-" + std::to_string(bit) : fault_names(mask).front();
      if ((faults & mask) != 0) {
        w.since[bit] = w.last;
        journal_fault({w.slot->name, name, "raised", w.slot->name + ": fault " + name, 4, std::nullopt, std::nullopt});
      } else {
        const std::uint64_t n = lost(*w.slot, w.since[bit], now);
        journal_fault({w.slot->name, name, "cleared",
                       w.slot->name + ": cleared " + name + " (" + std::to_string(n) + " samples per channel missing while it lasted)",
                       6, n, std::nullopt});
      }
    }
    w.faults = faults;
    w.last = now;
  }
}

void FaultJournal::finish(std::int64_t now_ns) {
  update(now_ns);  // a fault that cleared since the last check is reported as cleared
  for (Watched& w : watched_) {
    const Snapshot now = snapshot(*w.slot, now_ns);
    for (unsigned bit = 0; bit < 32; ++bit) {
      if ((w.faults & (1u << bit)) == 0) continue;
      const auto names = fault_names(1u << bit);
      const std::string name = names.empty() ? "fault-bit-" + std::to_string(bit) : names.front();
      const std::uint64_t n = lost(*w.slot, w.since[bit], now);
      journal_fault({w.slot->name, name, "active-at-stop",
                     w.slot->name + ": " + name + " still raised at stop (" + std::to_string(n) + " samples per channel missing so far)",
                     4, n, std::nullopt});
    }
  }
}

}  // namespace inertia::daq
