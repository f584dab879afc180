#include "daq/command_socket.hpp"

#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>

namespace inertia::daq {
namespace {

bool address_of(const std::filesystem::path& path, sockaddr_un& addr, std::string* why) {
  addr = sockaddr_un{};
  addr.sun_family = AF_UNIX;
  if (path.native().size() >= sizeof addr.sun_path) {
    if (why) *why = path.string() + ": a socket path must be shorter than " + std::to_string(sizeof addr.sun_path) + " bytes";
    return false;
  }
  std::memcpy(addr.sun_path, path.c_str(), path.native().size() + 1);
  return true;
}

std::string errno_text(const std::string& what) { return what + ": " + std::strerror(errno); }

std::vector<std::uint8_t> encode(const plan_command_t& m) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  (void)m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

}  // namespace

std::filesystem::path default_command_socket() {
  if (const char* runtime = std::getenv("RUNTIME_DIRECTORY"); runtime != nullptr && *runtime != '\0')
    return std::filesystem::path(std::string(runtime, std::strcspn(runtime, ":"))) / "command.sock";
  return "/run/inertia/command.sock";
}

std::unique_ptr<CommandSocket> CommandSocket::listen(const std::filesystem::path& path, std::string* why) {
  sockaddr_un addr{};
  if (!address_of(path, addr, why)) return nullptr;
  // A socket file left by a daemon that was killed: replace it, unless someone listens on it.
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0) {
    if (!S_ISSOCK(st.st_mode)) {
      if (why) *why = path.string() + " exists and is not a socket: remove it, or give the daemon another --command-socket";
      return nullptr;
    }
    hal::UniqueFd probe(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
    if (probe.valid() && ::connect(probe.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0) {
      if (why) *why = path.string() + ": another inertia-daqd listens on this command socket (one daemon per bench)";
      return nullptr;
    }
    ::unlink(path.c_str());
  }
  hal::UniqueFd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
  if (!fd.valid()) {
    if (why) *why = errno_text("command socket");
    return nullptr;
  }
  if (::bind(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    if (why)
      *why = errno_text("command socket " + path.string() + ": bind") +
             " (its directory must exist and be writable by the daemon: systemd's RuntimeDirectory=inertia makes "
             "/run/inertia; by hand, give --command-socket PATH)";
    return nullptr;
  }
  // Anyone local may connect; what each may do is decided from its credentials.
  if (::chmod(path.c_str(), 0666) != 0 || ::listen(fd.get(), 8) != 0) {
    if (why) *why = errno_text("command socket " + path.string());
    ::unlink(path.c_str());
    return nullptr;
  }
  return std::unique_ptr<CommandSocket>(new CommandSocket(path, std::move(fd)));
}

CommandSocket::~CommandSocket() {
  connections_.clear();
  listen_fd_.reset();
  ::unlink(path_.c_str());
}

void CommandSocket::add_poll_fds(std::vector<pollfd>& fds) const {
  fds.push_back({listen_fd_.get(), POLLIN, 0});
  for (const Connection& c : connections_) fds.push_back({c.fd.get(), POLLIN, 0});
}

std::vector<CommandSocket::Request> CommandSocket::take_requests() {
  for (;;) {
    hal::UniqueFd fd(::accept4(listen_fd_.get(), nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK));
    if (!fd.valid()) break;
    if (connections_.size() >= kMaxConnections) {
      ++dropped_;
      continue;   // closed: too many at once
    }
    Connection c;
    ucred cred{};
    socklen_t len = sizeof cred;
    if (::getsockopt(fd.get(), SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) {
      ++dropped_;
      continue;
    }
    c.peer.pid = cred.pid;
    c.peer.uid = cred.uid;
    c.peer.gid = cred.gid;
    gid_t groups[256];
    socklen_t glen = sizeof groups;
    if (::getsockopt(fd.get(), SOL_SOCKET, SO_PEERGROUPS, groups, &glen) == 0)
      c.peer.groups.assign(groups, groups + glen / sizeof(gid_t));
    c.fd = std::move(fd);
    connections_.push_back(std::move(c));
  }
  std::vector<Request> out;
  std::uint8_t buffer[kMaxMessage];
  for (auto it = connections_.begin(); it != connections_.end();) {
    bool closed = false;
    for (;;) {
      const ssize_t n = ::recv(it->fd.get(), buffer, sizeof buffer, MSG_TRUNC | MSG_DONTWAIT);
      if (n < 0) {
        closed = errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR;
        break;
      }
      if (n == 0) {
        closed = true;
        break;
      }
      if (static_cast<std::size_t>(n) > sizeof buffer) {
        ++dropped_;   // larger than any request: cut off by the kernel, never read as one
        continue;
      }
      Request r;
      r.connection = it->fd.get();
      r.peer = it->peer;
      if (r.command.decode(buffer, 0, static_cast<int>(n)) != n || r.command.status != plan_command_t::STATUS_REQUEST) {
        ++dropped_;
        continue;
      }
      out.push_back(std::move(r));
    }
    it = closed ? connections_.erase(it) : it + 1;
  }
  return out;
}

bool CommandSocket::reply(int connection, const plan_command_t& answer) {
  for (const Connection& c : connections_) {
    if (c.fd.get() != connection) continue;
    const std::vector<std::uint8_t> bytes = encode(answer);
    return ::send(c.fd.get(), bytes.data(), bytes.size(), MSG_NOSIGNAL | MSG_DONTWAIT) == static_cast<ssize_t>(bytes.size());
  }
  return false;
}

std::unique_ptr<CommandClient> CommandClient::connect(const std::filesystem::path& path, std::string* why) {
  sockaddr_un addr{};
  if (!address_of(path, addr, why)) return nullptr;
  hal::UniqueFd fd(::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0));
  if (!fd.valid()) {
    if (why) *why = errno_text("socket");
    return nullptr;
  }
  if (::connect(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    if (why)
      *why = errno_text("no daemon answers on " + path.string()) +
             " (is inertia-daqd running on this bench, with this --command-socket? from another machine: --lcm-url URL --key FILE)";
    return nullptr;
  }
  return std::unique_ptr<CommandClient>(new CommandClient(std::move(fd)));
}

bool CommandClient::send(const plan_command_t& request, std::string* why) {
  const std::vector<std::uint8_t> bytes = encode(request);
  if (::send(fd_.get(), bytes.data(), bytes.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(bytes.size())) {
    if (why) *why = errno_text("sending to the command socket");
    return false;
  }
  return true;
}

std::optional<plan_command_t> CommandClient::receive(double timeout_s, std::string* why) {
  pollfd p{fd_.get(), POLLIN, 0};
  const int ready = ::poll(&p, 1, static_cast<int>(timeout_s * 1000));
  if (ready <= 0) {
    if (why) *why = ready == 0 ? "no answer" : errno_text("poll");
    return std::nullopt;
  }
  std::uint8_t buffer[CommandSocket::kMaxMessage];
  const ssize_t n = ::recv(fd_.get(), buffer, sizeof buffer, 0);
  if (n <= 0) {
    if (why) *why = n == 0 ? "the daemon closed the connection" : errno_text("recv");
    return std::nullopt;
  }
  plan_command_t answer{};
  if (answer.decode(buffer, 0, static_cast<int>(n)) != n) {
    if (why) *why = "an answer that is not a plan_command_t";
    return std::nullopt;
  }
  return answer;
}

}  // namespace inertia::daq
