#pragma once
// Faults on the systemd journal as structured entries, so that
//   journalctl -u inertia-daqd DEVICE=accel      journalctl -u inertia-daqd FAULT=bus-off
// find them. Every entry carries MESSAGE (the text of the stderr line), PRIORITY, DEVICE, FAULT
// and FAULT_STATE (raised, cleared, active-at-stop, absent), and where it is known
// SAMPLES_LOST (samples per channel the device did not deliver, valid, while the fault lasted)
// or MESSAGES_LOST (log records lost to a full disk).
// The stderr line stays for runs without systemd. Under systemd stderr is itself a journal
// stream (JOURNAL_STREAM, systemd.exec(5)); then only the structured entry is written, so each
// event is in the journal once. Without a journal (no /run/systemd/journal/socket) the
// structured entry is dropped quietly and the stderr line is the record.
// Thread: the supervisor (FaultJournal) or any thread (journal_fault); not real-time.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "daq/device_slot.hpp"

namespace inertia::daq {

struct FaultEntry {
  std::string device;                 // DEVICE=: the bench file's device name, or "log"
  std::string fault;                  // FAULT=: the INERTIA_STATUS code (bus-off, modbus-gone, disk-full, absent ...)
  std::string state;                  // FAULT_STATE=
  std::string message;                // MESSAGE= and the stderr line (without the "inertia-daqd: " prefix)
  int priority = 4;                   // syslog priority: 3 err, 4 warning, 6 info
  std::optional<std::uint64_t> samples_lost;
  std::optional<std::uint64_t> messages_lost;
};

/// Writes the entry to the journal and, unless stderr is the journal, the line to stderr.
void journal_fault(const FaultEntry& entry);

/// What the test executive does, on the journal the same way: MESSAGE, PRIORITY,
/// PLAN_EVENT (command, settled, phase-start, phase-end, phase-failed, abort, safe-state,
/// operator-mark, refused, plan-end), and where known CASE, PHASE (its 0-based index and label,
/// "1 rotation") and DEVICE. `journalctl -u inertia-daqd PLAN_EVENT=abort` finds every abort.
struct PlanEntry {
  std::string event{};                // PLAN_EVENT=
  std::string message{};              // MESSAGE= and the stderr line (without the "inertia-daqd: " prefix)
  int priority = 6;                   // 6 info; 4 a failed phase or an abort; 3 a safe state not reached
  std::string case_name{};            // CASE=, empty: none
  std::string phase{};                // PHASE=, empty: none
  std::string device{};               // DEVICE=, empty: none
};
void journal_plan(const PlanEntry& entry);

/// Every operator request, accepted or refused, the same way: MESSAGE, PRIORITY, OPERATOR (who,
/// as verified: "uid 1000 (ana)", "key lab-pc-2", or "unsigned (...)" with what it claimed),
/// COMMAND (mark, end, stop, arm), RESULT (accepted, refused, ignored). `journalctl -u
/// inertia-daqd RESULT=refused` lists the refusals.
struct CommandEntry {
  std::string who{};                  // OPERATOR=
  std::string command{};              // COMMAND=
  std::string result{};               // RESULT=
  std::string message{};              // MESSAGE= and the stderr line
  int priority = 5;                   // 5 notice: accepted; 4 warning: refused or ignored
};
void journal_command(const CommandEntry& entry);

/// Whether fd 2 is the journal stream systemd connected (JOURNAL_STREAM names its device:inode).
bool stderr_is_journal();

/// Watches the fault bits of every device and journals each change. SAMPLES_LOST of a cleared
/// fault: nominal rate x its duration minus the valid samples per channel that arrived meanwhile
/// (from the supervisor check before it was seen raised until the one that saw it cleared, so
/// the window spans it whole). Wall-clock time: meaningful on real and paced simulated benches,
/// not on --fast runs (the simulator runs ahead of the clock; the count is then 0).
class FaultJournal {
 public:
  /// `now_ns`: when the devices started (the first window opens there).
  FaultJournal(std::vector<const DeviceSlot*> slots, std::int64_t now_ns);
  /// Supervisor thread, every loop (100 ms): one entry per fault raised or cleared since.
  void update(std::int64_t now_ns);
  /// At stop: an entry per fault still raised, with what it cost so far.
  void finish(std::int64_t now_ns);

 private:
  struct Snapshot {
    std::int64_t t_ns = 0;
    double valid_per_channel = 0.0;
  };
  struct Watched {
    const DeviceSlot* slot;
    std::uint32_t faults = 0;
    Snapshot last;                    // at the previous update()
    Snapshot since[32];               // per fault bit: the snapshot before it was seen raised
  };
  static Snapshot snapshot(const DeviceSlot& slot, std::int64_t now_ns);
  static std::uint64_t lost(const DeviceSlot& slot, const Snapshot& from, const Snapshot& to);

  std::vector<Watched> watched_;
};

}  // namespace inertia::daq
