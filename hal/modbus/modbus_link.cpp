#include "hal/modbus/modbus_link.hpp"

#include <arpa/inet.h>

#include <cerrno>
#include <cmath>

namespace inertia::hal::modbus {
namespace {

std::chrono::steady_clock::duration seconds(double s) {
  return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s));
}

void set_timeout(modbus_t* ctx, double s) {
  const auto sec = static_cast<std::uint32_t>(s);
  const auto usec = static_cast<std::uint32_t>(std::lround((s - sec) * 1e6));
  modbus_set_response_timeout(ctx, sec, usec);
}

bool is_exception(int err) { return err >= EMBXILFUN && err <= EMBXGTAR; }
bool is_link_error(int err) {
  // ENXIO/ENODEV: a serial adapter unplugged under an open descriptor.
  return err == ECONNRESET || err == EPIPE || err == EBADF || err == ENOTCONN || err == ECONNREFUSED ||
         err == ECONNABORTED || err == EHOSTUNREACH || err == ENETUNREACH || err == EIO || err == ENXIO ||
         err == ENODEV;
}

}  // namespace

bool ModbusConfig::is_valid(std::string* why) const {
  auto fail = [&](const std::string& what) {
    if (why) *why = "modbus device '" + name + "': " + what;
    return false;
  };
  if (is_rtu()) {
    if (serial.baud <= 0) return fail("baud " + std::to_string(serial.baud) + " must be positive");
    if (serial.parity != 'N' && serial.parity != 'E' && serial.parity != 'O')
      return fail(std::string("parity '") + serial.parity + "' is not N, E or O");
    if (serial.data_bits < 5 || serial.data_bits > 8) return fail("data_bits must be 5..8");
    if (serial.stop_bits != 1 && serial.stop_bits != 2) return fail("stop_bits must be 1 or 2");
    // Address 0 is the broadcast: slaves never answer it, so every read would time out.
    if (unit_id < 1 || unit_id > 247) return fail("unit_id " + std::to_string(unit_id) + " is outside 1..247 (RTU slave address)");
  } else {
    in_addr addr{};
    if (::inet_pton(AF_INET, host.c_str(), &addr) != 1) return fail("host '" + host + "' is not an IPv4 address");
    if (port < 1 || port > 65535) return fail("port " + std::to_string(port) + " is outside 1..65535");
    if (unit_id < 0 || unit_id > 247) return fail("unit_id " + std::to_string(unit_id) + " is outside 0..247");
  }
  if (!(response_timeout_s > 0.0 && response_timeout_s < 60.0)) return fail("response_timeout_s must be in (0, 60)");
  if (!(reconnect_initial_s > 0.0 && reconnect_initial_s <= reconnect_max_s))
    return fail("need 0 < reconnect_initial_s <= reconnect_max_s");
  if (timeouts_before_reconnect < 1) return fail("timeouts_before_reconnect must be at least 1");
  std::string inner;
  if (!map.is_valid(&inner)) return fail(inner);
  return true;
}

std::string ModbusConfig::endpoint() const {
  if (!is_rtu()) return host + ":" + std::to_string(port);
  return serial.device + " " + std::to_string(serial.baud) + " " + std::to_string(serial.data_bits) + serial.parity +
         std::to_string(serial.stop_bits);
}

std::unique_ptr<ModbusLink> ModbusLink::connect(const ModbusConfig& config, std::string* why) {
  if (!config.is_valid(why)) return nullptr;
  const std::string where = "modbus " + config.endpoint();
  modbus_t* ctx = config.is_rtu() ? modbus_new_rtu(config.serial.device.c_str(), config.serial.baud, config.serial.parity,
                                                   config.serial.data_bits, config.serial.stop_bits)
                                   : modbus_new_tcp(config.host.c_str(), config.port);
  if (ctx == nullptr) {
    if (why) *why = where + (config.is_rtu() ? ": modbus_new_rtu: " : ": modbus_new_tcp: ") + modbus_strerror(errno);
    return nullptr;
  }
  std::unique_ptr<ModbusLink> link(new ModbusLink(ctx, config));  // owns ctx from here on
  modbus_set_error_recovery(ctx, MODBUS_ERROR_RECOVERY_NONE);
  modbus_set_slave(ctx, config.unit_id);
  set_timeout(ctx, config.response_timeout_s);
  if (modbus_connect(ctx) != 0) {
    if (why) *why = where + ": connect: " + modbus_strerror(errno);
    return nullptr;
  }
  return link;
}

ModbusLink::ModbusLink(modbus_t* ctx, const ModbusConfig& config)
    : ctx_(ctx),
      initial_backoff_(seconds(config.reconnect_initial_s)),
      max_backoff_(seconds(config.reconnect_max_s)),
      backoff_(initial_backoff_),
      timeouts_before_reconnect_(config.timeouts_before_reconnect) {}

ModbusLink::~ModbusLink() {
  modbus_close(ctx_);
  modbus_free(ctx_);
}

void ModbusLink::record_error(int err) {
  ++health_.errors;
  health_.last_errno = err;
  health_.last_error = modbus_strerror(err);
}

void ModbusLink::drop_link() {
  modbus_close(ctx_);
  connected_ = false;
  ++health_.disconnects;
  consecutive_timeouts_ = 0;
  backoff_ = initial_backoff_;
  next_attempt_ = Clock::now() + backoff_;
}

bool ModbusLink::try_reconnect() {
  const auto now = Clock::now();
  if (now < next_attempt_) return false;
  ++health_.reconnect_attempts;
  modbus_close(ctx_);  // a failed connect may leave a socket behind
  if (modbus_connect(ctx_) == 0) {
    connected_ = true;
    ++health_.reconnects;
    backoff_ = initial_backoff_;
    return true;
  }
  record_error(errno);
  backoff_ = std::min(backoff_ * 2, max_backoff_);
  next_attempt_ = Clock::now() + backoff_;
  return false;
}

template <class Call>
int ModbusLink::call(Call&& request) {
  if (!connected_ && !try_reconnect()) {
    errno = ENOTCONN;
    return -1;
  }
  ++health_.requests;
  const int rc = request();
  if (rc >= 0) {
    consecutive_timeouts_ = 0;
    return rc;
  }
  const int err = errno;
  record_error(err);
  if (is_exception(err)) {
    ++health_.exceptions;  // the device answered; the link is fine
  } else if (err == ETIMEDOUT) {
    ++health_.timeouts;
    // A late answer would be taken for the next request's: drop what has arrived.
    modbus_flush(ctx_);
    if (++consecutive_timeouts_ >= timeouts_before_reconnect_) drop_link();
  } else if (is_link_error(err)) {
    drop_link();
  } else {
    ++health_.protocol_errors;
    modbus_flush(ctx_);
  }
  errno = err;
  return -1;
}

int ModbusLink::read_registers(RegisterKind kind, int address, std::span<std::uint16_t> out) {
  const int n = static_cast<int>(out.size());
  return call([&] {
    return kind == RegisterKind::Holding ? modbus_read_registers(ctx_, address, n, out.data())
                                         : modbus_read_input_registers(ctx_, address, n, out.data());
  });
}

int ModbusLink::write_registers(int address, std::span<const std::uint16_t> words) {
  return call([&] {
    if (words.size() == 1) return modbus_write_register(ctx_, address, words[0]);
    return modbus_write_registers(ctx_, address, static_cast<int>(words.size()), words.data());
  });
}

}  // namespace inertia::hal::modbus
