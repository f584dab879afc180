// The bench file's real-device tables: a register map that overlaps itself and a CAN
// signal that does not fit its frame are refused at load with file:line:column; Modbus RTU
// settings, CAN bit rates and FD mode, `optional`, `range`, and the positions the device check
// and the daemon quote when an interface, chip, line or serial port is not there.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "common/config/bench_config.hpp"
#include "common/input_error.hpp"

namespace {

using inertia::InputError;
using namespace inertia::config;
namespace fs = std::filesystem;

// A real bench needs no sensors or plan: only wiring. Line 1 is "[bench]".
const std::string kReal = "[bench]\nname = \"r\"\nbackend = \"real\"\nsample_rate_hz = 1000.0\n";  // 4 lines

class DeviceTables : public ::testing::Test {
 protected:
  fs::path write(const std::string& text) {
    const fs::path dir = fs::temp_directory_path() /
                         ("inertia_device_tables_" + std::to_string(::getpid()) + "_" +
                          ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir);
    const fs::path p = dir / "bench.toml";
    std::ofstream(p) << text;
    return p;
  }
  BenchConfig load(const std::string& text) { return load_bench_config(write(text)); }
  InputError error_of(const std::string& text) {
    try {
      (void)load(text);
    } catch (const InputError& e) {
      return e;
    }
    ADD_FAILURE() << "no InputError for:\n" << text;
    return InputError("none");
  }
};

std::string modbus(const std::string& device_keys, const std::string& registers) {
  return kReal + "[[modbus_device]]\nname = \"thermal\"\nrole = \"thermal\"\n" + device_keys + registers;
}

std::string reg(const std::string& name, int address, const std::string& kind, const std::string& type) {
  return "[[modbus_device.register]]\nname = \"" + name + "\"\naddress = " + std::to_string(address) + "\nkind = \"" + kind +
         "\"\ntype = \"" + type + "\"\n";
}

TEST_F(DeviceTables, OverlappingRegistersAreRefusedAtTheSecondOnesAddress) {
  // 7 lines before the registers, 5 per register: the second one's address is on line 15.
  const std::string text = modbus("", reg("angle", 10, "input", "f32") + reg("status", 11, "input", "u16"));
  const InputError e = error_of(text);
  EXPECT_EQ(e.where().line, 15u) << e.what();
  EXPECT_EQ(e.where().column, 11u) << e.what();
  const std::string what = e.what();
  EXPECT_NE(what.find("bench.toml:15:11"), std::string::npos) << what;
  EXPECT_NE(what.find("register 'status' (address 11) overlaps register 'angle' (addresses 10..11, line 8)"),
            std::string::npos)
      << what;
  // Holding and input registers are separate address spaces; neighbours do not overlap.
  EXPECT_NO_THROW(load(modbus("", reg("angle", 10, "input", "f32") + reg("setpoint", 11, "holding", "u16"))));
  EXPECT_NO_THROW(load(modbus("", reg("angle", 10, "input", "f32") + reg("status", 12, "input", "u16"))));
  // Declared in the other order, the 32-bit one is the one that overlaps.
  const InputError later = error_of(modbus("", reg("status", 11, "input", "u16") + reg("angle", 10, "input", "i32")));
  EXPECT_NE(std::string(later.what()).find("register 'angle' (addresses 10..11) overlaps register 'status'"),
            std::string::npos)
      << later.what();
}

std::string can(const std::string& device_keys, const std::string& signal_keys) {
  return kReal + "[[can_device]]\nname = \"adc\"\ninterface = \"can0\"\n" + device_keys +
         "[[can_device.signal]]\nname = \"x\"\nid = 0x101\n" + signal_keys;
}

TEST_F(DeviceTables, ACanSignalMustFitItsFrame) {
  // Classic CAN (the default): 8 bytes. Bytes 6..8 do not fit; the error points at bit_length.
  const InputError e = error_of(can("", "byte_offset = 6\nbit_length = 24\n"));
  EXPECT_EQ(e.where().line, 12u) << e.what();
  EXPECT_EQ(e.where().column, 14u) << e.what();
  EXPECT_NE(std::string(e.what()).find("runs past the 8-byte payload of a classic CAN frame"), std::string::npos) << e.what();
  EXPECT_NO_THROW(load(can("", "byte_offset = 5\nbit_length = 24\n")));
  // A bit offset counts too: 8 bits from bit 1 of byte 7 end in byte 8.
  EXPECT_THROW(load(can("", "byte_offset = 7\nbit_offset = 1\nbit_length = 8\n")), InputError);
  // CAN FD frames carry 64 bytes.
  const BenchConfig fd = load(can("fd = true\nbitrate = 1000000\ndbitrate = 5000000\n", "byte_offset = 60\nbit_length = 32\n"));
  EXPECT_TRUE(fd.can_devices[0].fd);
  EXPECT_EQ(fd.can_devices[0].bitrate, 1'000'000u);
  EXPECT_EQ(fd.can_devices[0].dbitrate, 5'000'000u);
  const InputError past64 = error_of(can("fd = true\n", "byte_offset = 62\nbit_length = 24\n"));
  EXPECT_NE(std::string(past64.what()).find("64-byte payload of a CAN FD frame"), std::string::npos) << past64.what();
  // A data-phase bit rate without FD is a contradiction, named at its key.
  const InputError dbr = error_of(can("dbitrate = 5000000\n", "bit_length = 8\n"));
  EXPECT_EQ(dbr.where().line, 8u) << dbr.what();
  EXPECT_NE(std::string(dbr.what()).find("needs fd = true"), std::string::npos) << dbr.what();
  EXPECT_THROW(load(can("bitrate = 2000000\n", "bit_length = 8\n")), InputError);  // above ISO 11898's 1 Mbit/s
}

TEST_F(DeviceTables, ModbusRtuSettingsAndTheirContradictions) {
  const BenchConfig b = load(modbus("transport = \"rtu\"\nserial_port = \"/dev/ttyUSB0\"\nbaud = 9600\nparity = \"none\"\n"
                                    "stop_bits = 2\nunit_id = 7\n",
                                    reg("temperature", 0, "input", "i16")));
  const ModbusDevice& m = b.modbus_devices[0];
  EXPECT_EQ(m.transport, ModbusTransport::Rtu);
  EXPECT_EQ(m.serial_port, "/dev/ttyUSB0");
  EXPECT_EQ(m.baud, 9600);
  EXPECT_EQ(m.parity, SerialParity::None);
  EXPECT_EQ(m.data_bits, 8);
  EXPECT_EQ(m.stop_bits, 2);
  EXPECT_EQ(m.unit_id, 7);
  EXPECT_EQ(m.endpoint_at.line, 9u);  // serial_port: what --check and the daemon quote
  // Defaults: Modbus over serial line's 8E1 at 19200.
  const BenchConfig d = load(modbus("transport = \"rtu\"\nserial_port = \"/dev/ttyS0\"\n", ""));
  EXPECT_EQ(d.modbus_devices[0].baud, 19200);
  EXPECT_EQ(d.modbus_devices[0].parity, SerialParity::Even);
  EXPECT_EQ(d.modbus_devices[0].stop_bits, 1);
  // Each transport's keys belong to it.
  const InputError host = error_of(modbus("transport = \"rtu\"\nserial_port = \"/dev/ttyS0\"\nhost = \"10.0.0.1\"\n", ""));
  EXPECT_NE(std::string(host.what()).find("is a TCP setting"), std::string::npos) << host.what();
  const InputError baud = error_of(modbus("baud = 9600\n", ""));
  EXPECT_NE(std::string(baud.what()).find("needs transport = \"rtu\""), std::string::npos) << baud.what();
  EXPECT_THROW(load(modbus("transport = \"rtu\"\n", "")), InputError);                 // serial_port required
  EXPECT_THROW(load(modbus("transport = \"rtu\"\nserial_port = \"/dev/ttyS0\"\nunit_id = 0\n", "")), InputError);  // broadcast
  EXPECT_THROW(load(modbus("transport = \"rtu\"\nserial_port = \"/dev/ttyS0\"\nparity = \"mark\"\n", "")), InputError);
  EXPECT_THROW(load(modbus("transport = \"udp\"\n", "")), InputError);
}

TEST_F(DeviceTables, OptionalRangeAndThePositionsTheCheckQuotes) {
  const std::string text = kReal +
                           "[[can_device]]\nname = \"adc\"\ninterface = \"can7\"\noptional = true\n"   // 5..8
                           "[[can_device.signal]]\nname = \"x\"\nid = 0x101\n"                          // 9..11
                           "[[gpiod_encoder]]\nname = \"enc\"\nchip = \"gpiochip3\"\nline_a = 17\nline_b = 27\n"  // 12..16
                           "kind = \"linear\"\nresolution = 1e-6\n"                                      // 17..18
                           "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\nhost = \"192.168.10.21\"\n"  // 19..22
                           + reg("angle", 0, "input", "f32") + "range = [-10.0, 10.0]\n";               // 23..28
  const BenchConfig b = load(text);
  EXPECT_TRUE(b.can_devices[0].availability.optional);
  EXPECT_EQ(b.can_devices[0].availability.where.line, 5u);
  EXPECT_EQ(b.can_devices[0].interface_at.line, 7u);
  EXPECT_FALSE(b.gpiod_encoders[0].availability.optional);
  EXPECT_EQ(b.gpiod_encoders[0].chip_at.line, 14u);
  EXPECT_EQ(b.gpiod_encoders[0].line_at[0].line, 15u);
  EXPECT_EQ(b.gpiod_encoders[0].line_at[1].line, 16u);
  EXPECT_EQ(b.gpiod_encoders[0].line_at[2].line, 12u);  // no marker line: the table
  EXPECT_EQ(b.modbus_devices[0].endpoint_at.line, 22u);
  EXPECT_DOUBLE_EQ(b.modbus_devices[0].registers[0].range_min, -10.0);
  EXPECT_DOUBLE_EQ(b.modbus_devices[0].registers[0].range_max, 10.0);
  EXPECT_EQ(b.modbus_devices[0].registers[0].where.line, 23u);
  EXPECT_THROW(load(kReal + "[[modbus_device]]\nname = \"t\"\nrole = \"table\"\n" + reg("a", 0, "input", "u16") +
                    "range = [5.0, 1.0]\n"),
               InputError);
  EXPECT_THROW(load(kReal + "[[can_device]]\nname = \"adc\"\noptional = \"yes\"\n[[can_device.signal]]\nname = \"x\"\nid = 1\n"),
               InputError);
}

TEST_F(DeviceTables, TwoRtuDevicesOnOneSerialPortAreRefusedAtTheSecondOnesPortWithTheFix) {
  // One master per RS-485 line: each [[modbus_device]] polls on its own, so two on one port would
  // talk over each other. Lines: the first device 5..10, the second's serial_port on line 15.
  const std::string rtu = "transport = \"rtu\"\nserial_port = \"/dev/ttyUSB0\"\n";
  const std::string text = modbus(rtu + "unit_id = 1\n", "") +
                           "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\n" + rtu + "unit_id = 2\n";
  const InputError e = error_of(text);
  EXPECT_EQ(e.where().line, 15u) << e.what();
  const std::string what = e.what();
  EXPECT_NE(what.find("already the line of [[modbus_device]] 'thermal' (line 9)"), std::string::npos) << what;
  EXPECT_NE(what.find("one master per RS-485 line"), std::string::npos) << what;
  EXPECT_NE(what.find("second adapter"), std::string::npos) << what;
  // Two adapters, or one on RTU and one on TCP, are fine.
  EXPECT_NO_THROW(load(modbus(rtu, "") + "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\n"
                                        "transport = \"rtu\"\nserial_port = \"/dev/ttyUSB1\"\n"));
  EXPECT_NO_THROW(load(modbus(rtu, "") + "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\nhost = \"10.0.0.2\"\n"));
  // Two names of one adapter (a by-id link and the device it points to) are one port.
  const fs::path dir = write("").parent_path();
  const fs::path tty = dir / "ttyUSB9";
  std::ofstream(tty) << "";
  fs::remove(dir / "by-id-adapter");
  fs::create_symlink(tty, dir / "by-id-adapter");
  EXPECT_THROW(load(modbus("transport = \"rtu\"\nserial_port = \"" + tty.string() + "\"\n", "") +
                    "[[modbus_device]]\nname = \"table\"\nrole = \"table\"\ntransport = \"rtu\"\nserial_port = \"" +
                    (dir / "by-id-adapter").string() + "\"\n"),
               InputError);
}

TEST_F(DeviceTables, PlausibleRangesStuckWatchesWrappingCountsAndLatencyFloors) {
  const BenchConfig b = load(can("latency_floor_ns = 120000\n", "bit_length = 16\nsigned = true\nmin = -5.0\nmax = 5.0\n"
                                                                "stuck_after_s = 0.01\n"
                                                                "[[can_device.signal]]\nname = \"n\"\nid = 0x101\nbyte_offset = 2\n"
                                                                "bit_length = 32\nwraps = true\n"));
  const CanDevice& d = b.can_devices[0];
  EXPECT_EQ(d.availability.latency_floor_ns, 120000);
  EXPECT_DOUBLE_EQ(d.signals[0].min, -5.0);
  EXPECT_DOUBLE_EQ(d.signals[0].max, 5.0);
  EXPECT_DOUBLE_EQ(d.signals[0].stuck_after_s, 0.01);
  EXPECT_TRUE(d.signals[1].wraps);
  EXPECT_TRUE(std::isinf(d.signals[1].min) && std::isinf(d.signals[1].max));
  // Each wrong value is named at its key (the signal's own keys start on line 11).
  const InputError order = error_of(can("", "min = 5.0\nmax = 1.0\n"));
  EXPECT_EQ(order.where().line, 12u) << order.what();
  EXPECT_NE(std::string(order.what()).find("must be greater than min"), std::string::npos) << order.what();
  const InputError counter = error_of(can("", "counter = true\nwraps = true\n"));
  EXPECT_EQ(counter.where().line, 12u) << counter.what();
  EXPECT_THROW(load(can("", "counter = true\nmax = 3.0\n")), InputError);   // a counter is no reading
  EXPECT_THROW(load(can("latency_floor_ns = -1\n", "")), InputError);
  EXPECT_THROW(load(can("", "stuck_after_s = -1.0\n")), InputError);
  EXPECT_THROW(load(can("", "wraps = 1\n")), InputError);
  // A Modbus register's stuck watch and a GPIO encoder's latency floor.
  const BenchConfig m = load(modbus("latency_floor_ns = 2000000\n", reg("t", 0, "input", "i16") + "stuck_after_s = 30.0\n"));
  EXPECT_EQ(m.modbus_devices[0].availability.latency_floor_ns, 2'000'000);
  EXPECT_DOUBLE_EQ(m.modbus_devices[0].registers[0].stuck_after_s, 30.0);
  const BenchConfig g = load(kReal + "[[gpiod_encoder]]\nname = \"enc\"\nline_a = 1\nline_b = 2\nkind = \"linear\"\n"
                                     "resolution = 1e-6\nlatency_floor_ns = 5000\n");
  EXPECT_EQ(g.gpiod_encoders[0].availability.latency_floor_ns, 5000);
}

}  // namespace
