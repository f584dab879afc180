#pragma once
// Who may command the bench. Two ways in, each carrying an identity the daemon can verify:
// - on this machine, the command socket (daq/command_socket.hpp): the kernel tells the peer's
//   uid and groups (SO_PEERCRED, SO_PEERGROUPS); an operator is root, the daemon's own user, or a
//   member of the operator group (default inertia-operators);
// - from another machine, a signed_command_t on INERTIA_COMMAND_SIGNED: HMAC-SHA256 under a key
//   the operators hold (a key file readable by its owner and group only), a timestamp within
//   kWindowS of the daemon's clock and a nonce not seen within it.
// Authority by command: the operator stop from anyone local (stopping is the safe direction) or
// any valid signature; marks and case ends from an operator; arming the plan, which starts
// motion, from an operator on this machine only.
// Thread: the executive's (a verifier keeps its nonces); the free functions from any thread.
// Not real-time. HMAC and the constant-time compare are OpenSSL's libcrypto.
#include <sys/types.h>

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "inertia/plan_command_t.hpp"
#include "inertia/signed_command_t.hpp"

namespace inertia::daq {

/// One operators' key: its id (in the key file and in every signed request) and its secret.
struct CommandKey {
  std::string id;
  std::array<std::uint8_t, 32> secret{};
};

/// A key file: one key per line, "<key-id> <64 hex digits>" (openssl rand -hex 32), '#' starts a
/// comment. Throws InputError naming the file, its line and the fix: a file readable or
/// writable by others than its owner and group (chmod 640), a malformed line, no key.
std::vector<CommandKey> load_command_keys(const std::filesystem::path& file);

/// The signature of a request (see signed_command_t.lcm for what is signed).
std::array<std::uint8_t, 32> command_mac(const CommandKey& key, std::int64_t utime_us, std::int64_t nonce,
                                         std::span<const std::uint8_t> command);

/// `command` signed with `key` at `utime_us` with `nonce`.
signed_command_t sign_command(const CommandKey& key, const plan_command_t& command, std::int64_t utime_us, std::int64_t nonce);

/// Checks signed requests against the daemon's keys: the key known, the signature right, the
/// time within the window, the nonce new. Remembers the nonces of the window.
class SignedCommandVerifier {
 public:
  static constexpr double kWindowS = 30.0;
  explicit SignedCommandVerifier(std::vector<CommandKey> keys) : keys_(std::move(keys)) {}

  struct Verdict {
    bool ok = false;
    bool repeat = false;    // the very request taken before, sent again (its answer was lost): answer, do not act
    std::string key_id;
    plan_command_t command{};
    std::string why;        // refused: why
  };
  /// `now_us`: the daemon's wall clock (microseconds since the epoch).
  Verdict verify(const signed_command_t& request, std::int64_t now_us);
  [[nodiscard]] bool has_keys() const noexcept { return !keys_.empty(); }

 private:
  std::vector<CommandKey> keys_;
  std::deque<std::pair<std::int64_t, std::pair<std::string, std::int64_t>>> seen_;   // (utime, (key, nonce)) in order
  std::map<std::pair<std::string, std::int64_t>, std::array<std::uint8_t, 32>> seen_macs_;   // the request taken per (key, nonce)
};

/// Who sent a request, as far as the daemon could verify it.
struct CommandOrigin {
  enum class Path { Socket, Signed, Unsigned, CommandLine };
  Path path = Path::Unsigned;
  bool operator_ = false;   // root, the daemon's user, a member of the operator group, or a valid key
  std::string who;          // the journal's OPERATOR=: "uid 1000 (ana)", "key lab-pc-2", "unsigned (ana@pc2:412)"
};

/// Whether `origin` may give `command` (plan_command_t::COMMAND_*); why not, if not.
std::optional<std::string> refusal(const CommandOrigin& origin, std::int8_t command, const std::string& operator_group);

/// The operator group's id, by name or number; nullopt when the system has no such group.
std::optional<gid_t> operator_group_id(const std::string& group);

/// Whether a peer with these credentials is an operator: root, `daemon_uid`, or in `group`.
bool is_operator(uid_t uid, gid_t gid, std::span<const gid_t> groups, uid_t daemon_uid, std::optional<gid_t> group);

/// "uid 1000 (ana)".
std::string describe_uid(uid_t uid);

}  // namespace inertia::daq
