// Who may command the bench (daq/command_auth.hpp), against known answers: the key file's rules,
// the signature (RFC 4231's HMAC-SHA256 test case 2 through OpenSSL, then our framing), the
// verifier's window, repeats and replays, and the authority each command needs.
#include "daq/command_auth.hpp"

#include <gtest/gtest.h>
#include <openssl/evp.h>
#include <sys/stat.h>

#include <fstream>

#include "common/input_error.hpp"
#include "tests/support/scratch_dirs.hpp"

namespace inertia::daq {
namespace {

const std::string kSecret = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";

std::filesystem::path key_file(const testing::TempDir& dir, const std::string& text, mode_t mode) {
  const auto p = dir.path / "command.key";
  std::ofstream(p) << text;
  ::chmod(p.c_str(), mode);
  return p;
}

plan_command_t mark(std::int64_t id) {
  plan_command_t c{};
  c.id = id;
  c.sender = "ana@pc2:1";
  c.command = plan_command_t::COMMAND_MARK;
  c.case_name = "table";
  c.status = plan_command_t::STATUS_REQUEST;
  return c;
}

TEST(CommandAuth, OpenSslsHmacSha256MeetsRfc4231) {
  // RFC 4231 test case 2: key "Jefe", data "what do ya want for nothing?".
  const std::string key = "Jefe", data = "what do ya want for nothing?";
  unsigned char mac[32];
  std::size_t n = 0;
  ASSERT_NE(EVP_Q_mac(nullptr, "HMAC", nullptr, "SHA256", nullptr, key.data(), key.size(),
                      reinterpret_cast<const unsigned char*>(data.data()), data.size(), mac, sizeof mac, &n),
            nullptr);
  char hex[65];
  for (int i = 0; i < 32; ++i) std::snprintf(hex + 2 * i, 3, "%02x", mac[i]);
  EXPECT_EQ(std::string(hex), "5bdcc146bf60754e6a042426089575c75a003f089d2739839dec58b964ec3843");
}

TEST(CommandAuth, AKeyFileIsReadOnlyWhenOthersCannotAndSaysWhatIsWrongWhereItIs) {
  testing::TempDir dir;
  const auto keys = load_command_keys(key_file(dir, "# keys\nlab-pc-2 " + kSecret + "  # the lab's PC\n\nother " +
                                                        std::string(64, 'f') + "\n", 0640));
  ASSERT_EQ(keys.size(), 2u);
  EXPECT_EQ(keys[0].id, "lab-pc-2");
  EXPECT_EQ(keys[0].secret[1], 0x11);
  EXPECT_EQ(keys[1].secret[31], 0xff);
  auto error = [&](const std::string& text, mode_t mode) {
    try {
      (void)load_command_keys(key_file(dir, text, mode));
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("k " + kSecret + "\n", 0644).find("open to every user (mode 644): anyone could sign commands with it. Fix: chmod 640"),
            std::string::npos);
  EXPECT_NE(error("k " + kSecret + "\n", 0602).find("(mode 602)"), std::string::npos);
  EXPECT_NE(error("\nk 0011\n", 0600).find(":2:1: the secret must be 64 hex digits"), std::string::npos);
  EXPECT_NE(error("k " + std::string(63, '0') + "g\n", 0600).find("the secret is not hex"), std::string::npos);
  EXPECT_NE(error("k " + kSecret + "\nk " + kSecret + "\n", 0600).find("key id 'k' is there twice"), std::string::npos);
  EXPECT_NE(error("# nothing\n", 0600).find("holds no key"), std::string::npos);
}

TEST(CommandAuth, TheVerifierTakesARequestOnceAnswersItsRepeatAndRefusesReplaysForgeriesAndStaleOnes) {
  testing::TempDir dir;
  const auto keys = load_command_keys(key_file(dir, "lab " + kSecret + "\n", 0600));
  SignedCommandVerifier v(keys);
  const std::int64_t now = 1'800'000'000'000'000;
  const signed_command_t good = sign_command(keys[0], mark(1), now - 1'000'000, 42);
  auto r = v.verify(good, now);
  EXPECT_TRUE(r.ok) << r.why;
  EXPECT_EQ(r.command.id, 1);
  EXPECT_EQ(r.command.case_name, "table");
  r = v.verify(good, now);   // the same bytes: a repeat
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(r.repeat);
  EXPECT_EQ(r.command.id, 1);
  r = v.verify(sign_command(keys[0], mark(2), now, 42), now);   // another request under a used nonce
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.repeat);
  EXPECT_EQ(r.why, "replayed: this request (key 'lab', nonce 42) was already taken");
  signed_command_t tampered = sign_command(keys[0], mark(3), now, 43);
  tampered.command.back() ^= 1;
  r = v.verify(tampered, now);
  EXPECT_NE(r.why.find("the signature does not match key 'lab'"), std::string::npos) << r.why;
  CommandKey other = keys[0];
  other.secret[5] ^= 0x80;
  r = v.verify(sign_command(other, mark(4), now, 44), now);
  EXPECT_NE(r.why.find("the signature does not match"), std::string::npos) << r.why;
  other.id = "stranger";
  r = v.verify(sign_command(other, mark(5), now, 45), now);
  EXPECT_EQ(r.why, "unknown key 'stranger'");
  // The window: 30 s either way.
  EXPECT_TRUE(v.verify(sign_command(keys[0], mark(6), now - 29'000'000, 46), now).ok);
  EXPECT_TRUE(v.verify(sign_command(keys[0], mark(7), now + 29'000'000, 47), now).ok);
  r = v.verify(sign_command(keys[0], mark(8), now - 31'000'000, 48), now);
  EXPECT_NE(r.why.find("stale: signed 31 s from the daemon's clock"), std::string::npos) << r.why;
  // Nonces are kept past the window (a stale request is refused as stale before that).
  EXPECT_FALSE(v.verify(good, now + 20'000'000).ok);
  SignedCommandVerifier none({});
  EXPECT_EQ(none.verify(good, now).why, "this daemon takes no signed commands (no command key file)");
}

TEST(CommandAuth, EachCommandNeedsItsAuthority) {
  using P = CommandOrigin::Path;
  const std::string group = "inertia-operators";
  const CommandOrigin stranger{P::Socket, false, "uid 1001 (bob), pid 7"};
  const CommandOrigin local_operator{P::Socket, true, "uid 1000 (ana), pid 8"};
  const CommandOrigin remote_operator{P::Signed, true, "key lab"};
  const CommandOrigin anonymous{P::Unsigned, false, "unsigned request claiming to be ana"};
  EXPECT_FALSE(refusal(stranger, plan_command_t::COMMAND_STOP, group));
  EXPECT_EQ(*refusal(stranger, plan_command_t::COMMAND_MARK, group),
            "not authorized: uid 1001 (bob), pid 7 is not in group inertia-operators (an administrator adds a person with: "
            "usermod -aG inertia-operators NAME)");
  EXPECT_TRUE(refusal(stranger, plan_command_t::COMMAND_END_CASE, group));
  EXPECT_TRUE(refusal(stranger, plan_command_t::COMMAND_ARM, group));
  for (std::int8_t c : {plan_command_t::COMMAND_MARK, plan_command_t::COMMAND_END_CASE, plan_command_t::COMMAND_STOP,
                        plan_command_t::COMMAND_ARM})
    EXPECT_FALSE(refusal(local_operator, c, group)) << int(c);
  EXPECT_FALSE(refusal(remote_operator, plan_command_t::COMMAND_MARK, group));
  EXPECT_FALSE(refusal(remote_operator, plan_command_t::COMMAND_STOP, group));
  EXPECT_NE(refusal(remote_operator, plan_command_t::COMMAND_ARM, group)->find("never over the network"), std::string::npos);
  EXPECT_TRUE(refusal(anonymous, plan_command_t::COMMAND_STOP, group)) << "an unsigned stop carries no one's word either";

  const gid_t operators = 4242;
  const std::vector<gid_t> none, in_it{27, 4242};
  EXPECT_TRUE(is_operator(0, 0, none, 999, operators));
  EXPECT_TRUE(is_operator(999, 999, none, 999, operators));      // the daemon's own user
  EXPECT_TRUE(is_operator(1000, 1000, in_it, 999, operators));
  EXPECT_TRUE(is_operator(1000, 4242, none, 999, operators));    // its primary group
  EXPECT_FALSE(is_operator(1000, 1000, none, 999, operators));
  EXPECT_FALSE(is_operator(1000, 1000, in_it, 999, std::nullopt));
  EXPECT_EQ(operator_group_id("4242"), std::optional<gid_t>(4242));
  EXPECT_EQ(operator_group_id("root"), std::optional<gid_t>(0));
  EXPECT_FALSE(operator_group_id("no-such-group-here"));
}

}  // namespace
}  // namespace inertia::daq
