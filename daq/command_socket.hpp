#pragma once
// The daemon's command socket on this machine: a Unix domain socket (SOCK_SEQPACKET: one
// request per message, boundaries kept), by default /run/inertia/command.sock (systemd's
// RuntimeDirectory). Any local user may connect, so that an operator stop works from any
// account and a refusal can be answered and journalled; what a request may do is decided from the
// peer's credentials, which the kernel gives and no client can forge (SO_PEERCRED, SO_PEERGROUPS;
// daq/command_auth.hpp). A request is a plan_command_t, LCM-encoded; each answer is one too.
// A message larger than kMaxMessage, or one that is not a plan_command_t, is dropped and
// counted; connections beyond kMaxConnections are closed at once.
//
// Thread: CommandSocket on the executive's thread only (non-blocking; poll() its fds);
// CommandClient in `inertia-daqd mark` / `arm`. Not real-time.
#include <poll.h>
#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "hal/unique_fd.hpp"
#include "inertia/plan_command_t.hpp"

namespace inertia::daq {

/// The kernel's account of a connected peer.
struct PeerCredentials {
  pid_t pid = 0;
  uid_t uid = 0;
  gid_t gid = 0;
  std::vector<gid_t> groups;   // supplementary groups at connect time
};

class CommandSocket {
 public:
  static constexpr std::size_t kMaxMessage = 4096;
  static constexpr std::size_t kMaxConnections = 16;

  /// Binds and listens at `path` (mode 0666). An existing socket file nobody listens on (a killed
  /// daemon's) is replaced; one another process listens on is an error. nullptr + why.
  static std::unique_ptr<CommandSocket> listen(const std::filesystem::path& path, std::string* why);
  ~CommandSocket();
  CommandSocket(const CommandSocket&) = delete;
  CommandSocket& operator=(const CommandSocket&) = delete;

  struct Request {
    int connection = -1;           // answer with reply(connection, ...)
    PeerCredentials peer;
    plan_command_t command{};
  };
  /// The descriptors to poll (POLLIN): the listening socket and every connection.
  void add_poll_fds(std::vector<pollfd>& fds) const;
  /// Accepts what is pending and reads every pending message (never blocks).
  std::vector<Request> take_requests();
  /// One answer on a connection; false when it has gone.
  bool reply(int connection, const plan_command_t& answer);

  [[nodiscard]] const std::filesystem::path& path() const noexcept { return path_; }
  [[nodiscard]] std::uint64_t dropped() const noexcept { return dropped_; }   // oversized, malformed, over the limit

 private:
  CommandSocket(std::filesystem::path path, hal::UniqueFd fd) : path_(std::move(path)), listen_fd_(std::move(fd)) {}
  struct Connection {
    hal::UniqueFd fd;
    PeerCredentials peer;
  };
  std::filesystem::path path_;
  hal::UniqueFd listen_fd_;
  std::vector<Connection> connections_;
  std::uint64_t dropped_ = 0;
};

/// A client's connection to the command socket.
class CommandClient {
 public:
  /// nullptr + why ("no daemon listens on ...: is inertia-daqd running on this bench?").
  static std::unique_ptr<CommandClient> connect(const std::filesystem::path& path, std::string* why);
  bool send(const plan_command_t& request, std::string* why);
  /// The next answer within `timeout_s`; nullopt on timeout or when the daemon closed.
  std::optional<plan_command_t> receive(double timeout_s, std::string* why);

 private:
  explicit CommandClient(hal::UniqueFd fd) : fd_(std::move(fd)) {}
  hal::UniqueFd fd_;
};

/// Where the daemon's command socket is: $RUNTIME_DIRECTORY/command.sock under systemd, else
/// /run/inertia/command.sock.
std::filesystem::path default_command_socket();

}  // namespace inertia::daq
