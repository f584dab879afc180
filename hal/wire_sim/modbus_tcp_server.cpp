#include "hal/wire_sim/modbus_tcp_server.hpp"

#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <vector>

namespace inertia::hal::wire_sim {

std::unique_ptr<ModbusTcpServer> ModbusTcpServer::start(const ModbusServerOptions& options, Tick tick,
                                                        std::string* why) {
  modbus_mapping_t* mapping = modbus_mapping_new_start_address(
      0, 0, 0, 0, static_cast<unsigned>(options.holding_start), static_cast<unsigned>(options.holding_count),
      static_cast<unsigned>(options.input_start), static_cast<unsigned>(options.input_count));
  if (mapping == nullptr) {
    if (why) *why = std::string("modbus_mapping_new_start_address: ") + modbus_strerror(errno);
    return nullptr;
  }
  std::unique_ptr<ModbusTcpServer> server(new ModbusTcpServer(options, std::move(tick), mapping));
  if (!server->restart(why)) return nullptr;
  return server;
}

ModbusTcpServer::ModbusTcpServer(const ModbusServerOptions& options, Tick tick, modbus_mapping_t* mapping)
    : options_(options), tick_(std::move(tick)), mapping_(mapping), port_(options.port) {}

ModbusTcpServer::~ModbusTcpServer() {
  stop();
  modbus_mapping_free(mapping_);
}

bool ModbusTcpServer::open_pty(std::string* why) {
  // Raw from the start: a slave in cooked mode would echo the replies back to the master, which
  // would read them as requests (the client sets raw mode too, but only once it opens).
  termios raw{};
  ::cfmakeraw(&raw);
  int master = -1, slave = -1;
  char name[128] = {};
  if (::openpty(&master, &slave, name, &raw, nullptr) != 0) {
    if (why) *why = std::string("openpty: ") + std::strerror(errno);
    return false;
  }
  listen_fd_.reset(master);
  pty_slave_.reset(slave);
  (void)::fcntl(master, F_SETFD, FD_CLOEXEC);
  (void)::fcntl(slave, F_SETFD, FD_CLOEXEC);
  tty_path_ = name;
  std::error_code ec;
  std::filesystem::remove(options_.rtu_link, ec);
  std::filesystem::create_symlink(tty_path_, options_.rtu_link, ec);
  if (ec) {
    if (why) *why = "symlink " + options_.rtu_link + " -> " + tty_path_ + ": " + ec.message();
    return false;
  }
  // libmodbus only reads and writes the descriptor we hand it; the device name and line settings
  // are never used on this side (a pty has no baud rate).
  ctx_ = modbus_new_rtu(tty_path_.c_str(), 115200, 'N', 8, 1);
  if (ctx_ == nullptr) {
    if (why) *why = std::string("modbus_new_rtu: ") + modbus_strerror(errno);
    return false;
  }
  modbus_set_slave(ctx_, options_.rtu_slave_id);
  modbus_set_socket(ctx_, master);
  return true;
}

bool ModbusTcpServer::listen(std::string* why) {
  if (!options_.rtu_link.empty()) return open_pty(why);
  ctx_ = modbus_new_tcp(options_.host.c_str(), port_);
  if (ctx_ == nullptr) {
    if (why) *why = std::string("modbus_new_tcp: ") + modbus_strerror(errno);
    return false;
  }
  const int fd = modbus_tcp_listen(ctx_, 8);
  if (fd < 0) {
    if (why) *why = "modbus_tcp_listen on " + options_.host + ":" + std::to_string(port_) + ": " + modbus_strerror(errno);
    modbus_free(ctx_);
    ctx_ = nullptr;
    return false;
  }
  listen_fd_.reset(fd);
  sockaddr_in addr{};
  socklen_t len = sizeof addr;
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0) port_ = ntohs(addr.sin_port);
  return true;
}

bool ModbusTcpServer::restart(std::string* why) {
  if (running()) return true;
  int p[2];
  if (::pipe2(p, O_CLOEXEC | O_NONBLOCK) != 0) {
    if (why) *why = std::string("pipe2: ") + std::strerror(errno);
    return false;
  }
  wake_read_.reset(p[0]);
  wake_write_.reset(p[1]);
  if (!listen(why)) return false;
  stop_ = false;
  thread_ = std::thread([this] { run(); });
  return true;
}

void ModbusTcpServer::stop() {
  if (!running()) return;
  stop_ = true;
  const char byte = 1;
  (void)!::write(wake_write_.get(), &byte, 1);
  thread_.join();
  listen_fd_.reset();
  pty_slave_.reset();
  // The connections were closed by the thread; the context must not close a stale socket.
  modbus_set_socket(ctx_, -1);
  modbus_free(ctx_);
  ctx_ = nullptr;
}

void ModbusTcpServer::with_registers(const std::function<void(modbus_mapping_t&)>& f) {
  std::lock_guard lock(mutex_);
  f(*mapping_);
}

void ModbusTcpServer::on_written(Written hook) {
  std::lock_guard lock(mutex_);
  written_ = std::move(hook);
}

void ModbusTcpServer::reply(const std::uint8_t* query, int length) {
  // Modbus application data unit after libmodbus' header (MBAP on TCP, slave address on RTU):
  // function code, start address (big-endian), and for FC16 the register count.
  const int at = modbus_get_header_length(ctx_);
  const int function = length > at ? query[at] : 0;
  int address = -1, count = 0;
  if ((function == MODBUS_FC_WRITE_SINGLE_REGISTER || function == MODBUS_FC_WRITE_MULTIPLE_REGISTERS) && length >= at + 5) {
    address = (query[at + 1] << 8) | query[at + 2];
    count = function == MODBUS_FC_WRITE_SINGLE_REGISTER ? 1 : ((query[at + 3] << 8) | query[at + 4]);
  }
  std::lock_guard lock(mutex_);
  const int first = address - mapping_->start_registers;
  const bool in_map = address >= 0 && count > 0 && first >= 0 && first + count <= mapping_->nb_registers;
  std::vector<std::uint16_t> before;
  if (in_map && written_) before.assign(mapping_->tab_registers + first, mapping_->tab_registers + first + count);
  modbus_reply(ctx_, query, length, mapping_);
  if (in_map && written_) written_(*mapping_, address, count, before.data());
}

void ModbusTcpServer::tick_when_due(std::chrono::steady_clock::time_point& last_tick) {
  const auto now = std::chrono::steady_clock::now();
  const double dt = std::chrono::duration<double>(now - last_tick).count();
  if (dt * 1000.0 < options_.tick_ms) return;
  last_tick = now;
  if (tick_) {
    std::lock_guard lock(mutex_);
    tick_(*mapping_, dt);
  }
}

void ModbusTcpServer::serve_rtu() {
  std::uint8_t query[MODBUS_RTU_MAX_ADU_LENGTH];
  auto last_tick = std::chrono::steady_clock::now();
  while (!stop_) {
    pollfd fds[2] = {{wake_read_.get(), POLLIN, 0}, {listen_fd_.get(), POLLIN, 0}};
    const int ready = ::poll(fds, 2, options_.tick_ms);
    if (stop_) break;
    if (ready > 0 && (fds[1].revents & POLLIN) != 0) {
      // > 0: a request for this slave; 0: one for another address (ignored, as on a shared
      // RS-485 line); < 0: a broken frame (CRC, timeout between bytes), already discarded.
      const int rc = modbus_receive(ctx_, query);
      if (rc > 0 && !silent_) {
        ++served_;   // before the answer leaves: a client holding it sees it counted
        reply(query, rc);
      }
    }
    tick_when_due(last_tick);
  }
}

void ModbusTcpServer::run() {
  if (!options_.rtu_link.empty()) {
    serve_rtu();
    return;
  }
  std::vector<int> clients;
  std::vector<pollfd> fds;
  std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
  auto last_tick = std::chrono::steady_clock::now();
  while (!stop_) {
    fds.clear();
    fds.push_back({wake_read_.get(), POLLIN, 0});
    fds.push_back({listen_fd_.get(), POLLIN, 0});
    for (int c : clients) fds.push_back({c, POLLIN, 0});
    const int ready = ::poll(fds.data(), fds.size(), options_.tick_ms);
    if (stop_) break;
    if (ready > 0) {
      if ((fds[1].revents & POLLIN) != 0) {
        const int c = ::accept4(listen_fd_.get(), nullptr, nullptr, SOCK_CLOEXEC);
        if (c >= 0) clients.push_back(c);
      }
      for (std::size_t i = 2; i < fds.size(); ++i) {
        if (fds[i].revents == 0) continue;
        const int c = fds[i].fd;
        modbus_set_socket(ctx_, c);
        const int rc = modbus_receive(ctx_, query);
        if (rc > 0) {
          if (!silent_) {
            ++served_;
            reply(query, rc);
          }
        } else if (rc < 0) {
          ::close(c);
          std::erase(clients, c);
        }
      }
    }
    tick_when_due(last_tick);
  }
  for (int c : clients) ::close(c);
}

}  // namespace inertia::hal::wire_sim
