#include "hal/wire_sim/modbus_tcp_server.hpp"

#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
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

bool ModbusTcpServer::listen(std::string* why) {
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
  // The connections were closed by the thread; the context must not close a stale socket.
  modbus_set_socket(ctx_, -1);
  modbus_free(ctx_);
  ctx_ = nullptr;
}

void ModbusTcpServer::with_registers(const std::function<void(modbus_mapping_t&)>& f) {
  std::lock_guard lock(mutex_);
  f(*mapping_);
}

void ModbusTcpServer::run() {
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
            std::lock_guard lock(mutex_);
            modbus_reply(ctx_, query, rc, mapping_);
            ++served_;
          }
        } else if (rc < 0) {
          ::close(c);
          std::erase(clients, c);
        }
      }
    }
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - last_tick).count();
    if (dt * 1000.0 >= options_.tick_ms) {
      last_tick = now;
      if (tick_) {
        std::lock_guard lock(mutex_);
        tick_(*mapping_, dt);
      }
    }
  }
  for (int c : clients) ::close(c);
}

}  // namespace inertia::hal::wire_sim
