#include "daq/command_auth.hpp"

#include <grp.h>
#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <pwd.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "common/input_error.hpp"

namespace inertia::daq {
namespace {

constexpr std::string_view kDomain = "inertia-command-v1";

std::uint8_t* put_be64(std::uint8_t* out, std::int64_t v) {
  for (int shift = 56; shift >= 0; shift -= 8) *out++ = static_cast<std::uint8_t>(static_cast<std::uint64_t>(v) >> shift);
  return out;
}

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

std::vector<CommandKey> load_command_keys(const std::filesystem::path& file) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0)
    throw InputError(file.string() + ": the command key file cannot be read: " + std::strerror(errno));
  if ((st.st_mode & S_IRWXO) != 0)
    throw InputError(file.string() + ": the command key file is open to every user (mode " +
                     [&] {
                       std::ostringstream m;
                       m << std::oct << (st.st_mode & 07777);
                       return m.str();
                     }() +
                     "): anyone could sign commands with it. Fix: chmod 640 " + file.string() +
                     " (and chgrp inertia-operators " + file.string() + ")");
  std::ifstream in(file);
  if (!in) throw InputError(file.string() + ": the command key file cannot be read");
  std::vector<CommandKey> keys;
  std::string line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::istringstream words(line);
    std::string id, hex, extra;
    if (!(words >> id)) continue;
    auto fail = [&](const std::string& what) {
      throw InputError(SourcePosition{file.string(), number, 1},
                       what + " (a key line is \"<key-id> <64 hex digits>\"; make a key with: openssl rand -hex 32)");
    };
    if (!(words >> hex) || (words >> extra)) fail("expected a key id and its secret");
    if (hex.size() != 64) fail("the secret must be 64 hex digits (32 bytes)");
    CommandKey k;
    k.id = id;
    for (std::size_t i = 0; i < 32; ++i) {
      const int hi = hex_digit(hex[2 * i]), lo = hex_digit(hex[2 * i + 1]);
      if (hi < 0 || lo < 0) fail("the secret is not hex");
      k.secret[i] = static_cast<std::uint8_t>(hi * 16 + lo);
    }
    if (std::any_of(keys.begin(), keys.end(), [&](const CommandKey& other) { return other.id == id; }))
      fail("key id '" + id + "' is there twice");
    keys.push_back(k);
  }
  if (keys.empty()) throw InputError(file.string() + ": the command key file holds no key (\"<key-id> <64 hex digits>\")");
  return keys;
}

std::array<std::uint8_t, 32> command_mac(const CommandKey& key, std::int64_t utime_us, std::int64_t nonce,
                                         std::span<const std::uint8_t> command) {
  // domain | key id | 0 | utime (big-endian) | nonce (big-endian) | command bytes
  std::vector<std::uint8_t> message(kDomain.size() + key.id.size() + 1 + 2 * sizeof(std::int64_t) + command.size());
  std::uint8_t* out = std::copy(kDomain.begin(), kDomain.end(), message.data());
  out = std::copy(key.id.begin(), key.id.end(), out);
  *out++ = 0;
  out = put_be64(out, utime_us);
  out = put_be64(out, nonce);
  std::copy(command.begin(), command.end(), out);
  std::array<std::uint8_t, 32> mac{};
  std::size_t length = 0;
  if (EVP_Q_mac(nullptr, "HMAC", nullptr, "SHA256", nullptr, key.secret.data(), key.secret.size(), message.data(),
                message.size(), mac.data(), mac.size(), &length) == nullptr ||
      length != mac.size())
    throw std::runtime_error("HMAC-SHA256 failed (OpenSSL)");
  return mac;
}

signed_command_t sign_command(const CommandKey& key, const plan_command_t& command, std::int64_t utime_us, std::int64_t nonce) {
  signed_command_t s{};
  s.utime = utime_us;
  s.nonce = nonce;
  s.key_id = key.id;
  s.command.resize(static_cast<std::size_t>(command.getEncodedSize()));
  (void)command.encode(s.command.data(), 0, static_cast<int>(s.command.size()));
  s.command_size = static_cast<std::int32_t>(s.command.size());
  const auto mac = command_mac(key, utime_us, nonce, s.command);
  std::copy(mac.begin(), mac.end(), s.mac);
  return s;
}

SignedCommandVerifier::Verdict SignedCommandVerifier::verify(const signed_command_t& request, std::int64_t now_us) {
  Verdict v;
  v.key_id = request.key_id;
  const auto window_us = static_cast<std::int64_t>(kWindowS * 1e6);
  while (!seen_.empty() && seen_.front().first < now_us - 2 * window_us) {
    seen_macs_.erase(seen_.front().second);
    seen_.pop_front();
  }
  const auto key = std::find_if(keys_.begin(), keys_.end(), [&](const CommandKey& k) { return k.id == request.key_id; });
  if (key == keys_.end()) {
    v.why = keys_.empty() ? "this daemon takes no signed commands (no command key file)" : "unknown key '" + request.key_id + "'";
    return v;
  }
  const auto mac = command_mac(*key, request.utime, request.nonce, request.command);
  if (CRYPTO_memcmp(mac.data(), request.mac, mac.size()) != 0) {
    v.why = "the signature does not match key '" + request.key_id + "' (a forged or damaged request, or another key)";
    return v;
  }
  const double age_s = static_cast<double>(now_us - request.utime) * 1e-6;
  if (std::abs(age_s) > kWindowS) {
    std::ostringstream why;
    why << "stale: signed " << age_s << " s from the daemon's clock, outside +-" << kWindowS << " s (a replay, or the clocks differ)";
    v.why = why.str();
    return v;
  }
  if (v.command.decode(request.command.data(), 0, request.command_size) < 0) {
    v.why = "the signed command is not a plan_command_t";
    return v;
  }
  const std::pair<std::string, std::int64_t> id{request.key_id, request.nonce};
  if (const auto taken = seen_macs_.find(id); taken != seen_macs_.end()) {
    // The same bytes again are a sender repeating a request whose answer it lost: answered again,
    // not acted on twice. Anything else under a nonce already used is a replay.
    if (taken->second == mac) {
      v.repeat = true;
    } else {
      v.command = plan_command_t{};
      v.why = "replayed: this request (key '" + request.key_id + "', nonce " + std::to_string(request.nonce) + ") was already taken";
    }
    return v;
  }
  seen_.emplace_back(request.utime, id);
  seen_macs_.emplace(id, mac);
  v.ok = true;
  return v;
}

std::optional<std::string> refusal(const CommandOrigin& origin, std::int8_t command, const std::string& operator_group) {
  using P = CommandOrigin::Path;
  if (origin.path == P::Unsigned)
    return "not authorized: an unsigned request on INERTIA_COMMAND carries no identity; from this machine use the command "
           "socket (inertia-daqd mark, arm), from another sign it with a command key (--key FILE)";
  if (command == plan_command_t::COMMAND_STOP) return std::nullopt;   // stopping is the safe direction
  if (!origin.operator_)
    return "not authorized: " + origin.who + " is not in group " + operator_group +
           " (an administrator adds a person with: usermod -aG " + operator_group + " NAME)";
  if (command == plan_command_t::COMMAND_ARM && origin.path == P::Signed)
    return "not authorized: arming starts motion and is taken only on this machine (inertia-daqd arm on the bench PC), "
           "never over the network";
  return std::nullopt;
}

std::optional<gid_t> operator_group_id(const std::string& group) {
  if (!group.empty() && std::all_of(group.begin(), group.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return static_cast<gid_t>(std::stoul(group));
  const struct group* g = ::getgrnam(group.c_str());
  if (g == nullptr) return std::nullopt;
  return g->gr_gid;
}

bool is_operator(uid_t uid, gid_t gid, std::span<const gid_t> groups, uid_t daemon_uid, std::optional<gid_t> group) {
  if (uid == 0 || uid == daemon_uid) return true;
  if (!group) return false;
  return gid == *group || std::find(groups.begin(), groups.end(), *group) != groups.end();
}

std::string describe_uid(uid_t uid) {
  const passwd* pw = ::getpwuid(uid);
  return "uid " + std::to_string(uid) + (pw != nullptr ? " (" + std::string(pw->pw_name) + ")" : std::string());
}

}  // namespace inertia::daq
