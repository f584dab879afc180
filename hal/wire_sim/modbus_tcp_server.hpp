#pragma once
// A real Modbus TCP server on loopback (libmodbus: modbus_tcp_listen, modbus_receive,
// modbus_reply against a modbus_mapping_t) in its own thread, so the client code under test
// talks to it over a real socket. Several clients at once (poll loop, as libmodbus'
// bandwidth-server-many-up example). Faults: stop()/restart() (server gone and back on the same
// port) and silence (requests read, never answered -> client timeouts).
//
// With options.rtu_link set the same server speaks Modbus RTU instead, on the master side of a
// pseudo-terminal pair (openpty): the client opens the slave side by a path, as it opens
// /dev/ttyUSB0, and the bytes cross a real tty with its termios. rtu_link is a symbolic link to
// that slave, as udev's /dev/serial/by-id names an adapter: stop() closes the pty (the adapter
// is unplugged: the client's descriptor fails and the device file goes), restart() opens a new
// one behind the same link (plugged back).
#include <modbus/modbus.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "hal/unique_fd.hpp"

namespace inertia::hal::wire_sim {

struct ModbusServerOptions {
  std::string host = "127.0.0.1";
  int port = 0;                       // 0: the kernel picks a free port (see port())
  int holding_start = 0, holding_count = 16;
  int input_start = 0, input_count = 16;
  int tick_ms = 20;                   // period of the tick hook (device physics)
  std::string rtu_link;               // non-empty: Modbus RTU on a pty, this symlink names it
  int rtu_slave_id = 1;               // RTU: the address this server answers (others are ignored)
};

class ModbusTcpServer {
 public:
  /// Called every tick_ms in the server thread with the register lock held; dt_s since last.
  using Tick = std::function<void(modbus_mapping_t& registers, double dt_s)>;
  /// Called in the server thread, register lock held, right after a write request (FC6, FC16)
  /// to holding registers [address, address + count) was answered; `before` holds their words
  /// from before the write (a device model may take the value at once, or put them back).
  using Written = std::function<void(modbus_mapping_t& registers, int address, int count, const std::uint16_t* before)>;

  /// Listens and starts the thread; nullptr with the reason on failure.
  static std::unique_ptr<ModbusTcpServer> start(const ModbusServerOptions& options, Tick tick, std::string* why);
  ~ModbusTcpServer();
  ModbusTcpServer(const ModbusTcpServer&) = delete;
  ModbusTcpServer& operator=(const ModbusTcpServer&) = delete;

  /// Closes the listening socket and every connection and joins the thread (returns within one
  /// poll wake-up). Registers are kept. Thread: any except the server thread.
  void stop();
  /// Listens again on the same port (SO_REUSEADDR) with the same registers.
  bool restart(std::string* why);
  [[nodiscard]] bool running() const noexcept { return thread_.joinable(); }
  [[nodiscard]] int port() const noexcept { return port_; }
  /// RTU: the pty slave the link points to now (changes at every restart()).
  [[nodiscard]] const std::string& tty_path() const noexcept { return tty_path_; }

  /// Runs f on the registers with the lock held (the hook to set or read values). Thread: any.
  void with_registers(const std::function<void(modbus_mapping_t&)>& f);
  /// While silent the server reads requests but answers none.
  void set_silent(bool silent) noexcept { silent_ = silent; }
  /// The write hook (see Written). Thread: any; takes the register lock.
  void on_written(Written hook);
  /// Requests answered, counted before each answer is written (a client that has its answer
  /// sees it counted). Thread: any.
  [[nodiscard]] std::uint64_t requests_served() const noexcept { return served_.load(); }

 private:
  ModbusTcpServer(const ModbusServerOptions& options, Tick tick, modbus_mapping_t* mapping);
  bool listen(std::string* why);
  bool open_pty(std::string* why);
  void run();
  void serve_rtu();
  void tick_when_due(std::chrono::steady_clock::time_point& last_tick);
  /// modbus_reply under the lock, then the write hook for a write request. Server thread.
  void reply(const std::uint8_t* query, int length);

  ModbusServerOptions options_;
  Tick tick_;
  Written written_;                   // guarded by mutex_
  modbus_mapping_t* mapping_;         // owned
  std::mutex mutex_;                  // guards mapping_
  modbus_t* ctx_ = nullptr;           // owned; used by the server thread only while it runs
  UniqueFd listen_fd_;                // TCP: the listening socket; RTU: the pty master
  UniqueFd pty_slave_;                // RTU: held open so the master never reads a hang-up between clients
  std::string tty_path_;
  UniqueFd wake_read_, wake_write_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> silent_{false};
  std::atomic<std::uint64_t> served_{0};
  int port_ = 0;
};

}  // namespace inertia::hal::wire_sim
