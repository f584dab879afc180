#pragma once
// `--log FILE` for characterize and diagnose: an event log of inertia-daqd (or lcm-logger) ->
// StreamAssembler -> the same in-memory dataset::Dataset read_dataset gives for a folder.
#include <filesystem>
#include <iosfwd>
#include <string>

#include "analyzer/fusion/stream_assembler.hpp"
#include "common/dataset/dataset.hpp"

namespace inertia::fusion {

/// Feeds every INERTIA_BENCH, INERTIA_RAW_* and INERTIA_EVENT message of `file` to `assembler`
/// in log order (other channels are skipped), then finish(). Throws InputError naming the file,
/// the event index and the byte offset for a file that is not an LCM log or a message that does
/// not decode; a log cut inside its last event is read up to it (noted on `messages`).
void feed_log(const std::filesystem::path& file, StreamAssembler& assembler, std::ostream& messages);

/// The dataset of sensor `sensor` (empty: the bench's only one) recorded in `file`: one dataset
/// case per contiguous valid stretch of each test case (the first keeps the case's name, the
/// others get "-seg2", "-seg3", ... and share its mounting), kind, nominal m_ec and mounting from
/// the bench file as `simulate` writes them. Excluded samples, gaps and notes are summarized on
/// `messages`. InputError for bad input (see feed_log, StreamAssembler::finish) and when no case
/// has a usable stretch.
dataset::Dataset log_dataset(const std::filesystem::path& file, const std::string& sensor, std::ostream& messages,
                             const AssemblerOptions& options = {});

/// A fused segment as dataset rows of its test case `tc`: name, kind, nominal m_ec and mounting
/// from the plan (as `simulate` writes them), the samples and phase labels moved in.
dataset::CaseData to_case_data(FusedSegment&& segment, const config::TestCase& tc);

}  // namespace inertia::fusion
