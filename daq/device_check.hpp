#pragma once
// inertia-daqd --check --config FILE: opens every device of the bench file without sampling and
// says, per device and per thing it needs, whether it is there and set up as the bench file
// expects:
//   CAN     the kernel has SocketCAN; the interface exists, is CAN, is up, at the bit rates and
//           in the FD mode the bench wants, its controller not bus-off; a CAN_RAW socket binds
//           with the device's filters;
//   GPIO    the chip opens; each line exists, is free and takes a both-edge event request;
//   Modbus  the server answers (TCP) or the serial port opens (RTU); each mapped register reads,
//           alone, and its value is within its range.
// Every failure carries the bench-file position it is about and the command that fixes it.
// The daemon uses the same rows to say why a device did not open at start (real_bench.cpp).
// Control thread only; not real-time (opens sockets, waits for Modbus answers).
#include <iosfwd>
#include <string>
#include <vector>

#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"

namespace inertia::daq {

enum class CheckStatus { Ok, Warn, Fail };
const char* to_string(CheckStatus status) noexcept;

struct CheckRow {
  std::string device;       // the device's name in the bench file
  std::string kind;         // "CAN", "GPIO", "Modbus TCP", "Modbus RTU"
  std::string item;         // what was checked: "interface can0", "line 17 (line_a)", "register temperature"
  CheckStatus status = CheckStatus::Ok;
  std::string detail;       // what was found
  std::string fix;          // Warn/Fail: the command (or edit) that fixes it
  SourcePosition where;     // the bench-file key the row is about
  bool optional = false;    // the device has optional = true
};

std::vector<CheckRow> check_can_device(const config::CanDevice& device);
std::vector<CheckRow> check_gpiod_encoder(const config::GpiodEncoder& encoder);
/// With `bench` (the bench it belongs to), also the heartbeat against the bench's stop_within_s.
std::vector<CheckRow> check_modbus_device(const config::ModbusDevice& device, const config::BenchConfig* bench = nullptr);
/// Every device of the bench, in file order by kind (CAN, GPIO, Modbus).
std::vector<CheckRow> check_bench(const config::BenchConfig& bench);

/// The table, then one line per failing device and the verdict.
void print_check_table(std::ostream& out, const config::BenchConfig& bench, const std::vector<CheckRow>& rows);
/// 0 when no row of a required device failed, 2 (bad input: the bench file names what is not
/// there) otherwise. Warnings and optional devices do not change it.
int check_exit_status(const std::vector<CheckRow>& rows);
/// "FILE:LINE:COLUMN: device 'adc0' (CAN) interface can0: no such interface\n  fix: ..." for the
/// daemon's start-up error.
std::string format_failure(const CheckRow& row);

/// Loads `config_path` (InputError on a bad file), checks, prints to `out`; the exit status.
int run_device_check(const std::string& config_path, std::ostream& out);

}  // namespace inertia::daq
